"""Vehicle low beams as light sources: the ego's and those of the vehicles nearest to it.

The camera shaders light every fragment with at most :data:`MAX_LIGHTS` low beams (a uniform array), so a frame
keeps the ego's low beam first and then those of the nearest vehicles; each camera then drops the beams that cannot
reach what it sees (:func:`beams_in_view`). A vehicle's two low beams are one light at the middle of its front face
(two lamps 1.2 m apart light the road ahead alike). Tail and brake lamps glow (``actor_mesh`` draws them emissive)
but light nothing: their light on the road is faint, and each light costs every pixel of a software rasteriser.
The beam's shape is in the shader (``shaders._SPOTS``); here are positions, directions and colours, and for each
beam the one vehicle standing in it nearest to the lamp (:func:`beam_blockers`): the shader darkens what lies
behind that vehicle as the lamp sees it, so a car does not light the road through the car in front of it.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np

from b2d_data.sim.api import ActorKind, ActorState
from b2d_data.sim.builtin.sensors.actor_mesh import light_flags

#: Most low beams a fragment is lit by (the size of the shaders' uniform arrays).
MAX_LIGHTS = 8
#: Low-beam colour (halogen white) times strength: the light a surface facing the beam gets 1 m in front of it.
LOW_BEAM_COLOR = (1.5, 1.425, 1.23)
#: Vehicles farther from the ego than this (m) light nothing the cameras would see lit.
LOW_BEAM_RANGE = 90.0
#: A beam lights a cone ahead of its lamp: this sphere (centre this far ahead, radius) holds what it lights visibly.
BEAM_BOUND = (20.0, 28.0)
#: The lamps sit 5 cm outside the box, so a vehicle's own body never faces its light.
_OUTSIDE = 0.05
#: Vehicles farther from a lamp than this (m) are not looked at as its blocker.
BLOCKER_RANGE = 45.0
#: Blocker distance of a beam with none.
NO_BLOCKER = 1.0e6


@dataclass(frozen=True)
class SpotLights:
    """Low beams of one frame: world positions (N, 3), unit directions (N, 3), RGB strengths (N, 3).

    ``own``: the first beam is that of the vehicle the cameras ride on (it also lights the fog in front of them).
    ``blocker`` (N, 4): unit direction from the lamp to the vehicle standing in the beam and the cosine of the half
    angle it covers; ``block_distance`` (N,): how far from the lamp its shadow starts (:data:`NO_BLOCKER`: none).
    """

    position: np.ndarray
    direction: np.ndarray
    color: np.ndarray
    own: bool = False
    blocker: np.ndarray | None = None
    block_distance: np.ndarray | None = None

    def __len__(self) -> int:
        return int(len(self.position))

    @classmethod
    def empty(cls) -> SpotLights:
        """No lights."""
        z = np.zeros((0, 3))
        return cls(z, z, z, False, np.zeros((0, 4)), np.zeros(0))

    def subset(self, keep: np.ndarray) -> SpotLights:
        """The beams at indices ``keep`` (in order); ``own`` stays only when the first beam is kept first."""
        keep = np.asarray(keep, np.int64)
        own = self.own and len(keep) > 0 and int(keep[0]) == 0
        blocker = None if self.blocker is None else self.blocker[keep]
        distance = None if self.block_distance is None else self.block_distance[keep]
        return SpotLights(self.position[keep], self.direction[keep], self.color[keep], own, blocker, distance)


def low_beam(actor: ActorState, matrix: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """World position (middle of the front face, at the head lamps' height) and direction of a vehicle's low beam
    (``matrix``: the actor's transform matrix when the caller has it)."""
    m = actor.transform.matrix() if matrix is None else matrix
    bb = actor.bounding_box
    c, e = bb.location, bb.extent
    # Head lamps as actor_mesh draws them on cars: 42 % of the box height up its front face.
    local = np.array([c.x + e.x + _OUTSIDE, c.y, c.z - e.z + 0.84 * e.z])
    return m[:3, :3] @ local + m[:3, 3], m[:3, :3] @ np.array([1.0, 0.0, 0.0])


def vehicle_lights(
    actors: Iterable[ActorState], ego: ActorState, night: bool, timestamp: float, limit: int = MAX_LIGHTS
) -> SpotLights:
    """The lit low beams (``actor_mesh.light_flags``) of the ego, first, and of the vehicles nearest to it."""
    centre = ego.transform.location.to_array()
    vehicles = [a for a in actors if a.kind is ActorKind.VEHICLE and a.id != ego.id]
    # Each vehicle's matrix serves its lamp and its blocking box.
    matrices = {a.id: a.transform.matrix() for a in (ego, *vehicles)}
    own = light_flags(ego, night, timestamp).beam
    beams = [(ego, *low_beam(ego, matrices[ego.id]))] if own else []
    others = []
    for actor in vehicles:
        if not light_flags(actor, night, timestamp).beam:
            continue
        pos, direction = low_beam(actor, matrices[actor.id])
        distance = float(np.linalg.norm(pos - centre))
        if distance <= LOW_BEAM_RANGE:
            others.append((distance, actor.id, actor, pos, direction))
    others.sort(key=lambda beam: beam[:2])
    beams += [(actor, pos, direction) for _, _, actor, pos, direction in others]
    beams = beams[:limit]
    if not beams:
        return SpotLights.empty()
    position = np.array([b[1] for b in beams], np.float64)
    direction = np.array([b[2] for b in beams], np.float64)
    blocker, block_distance = beam_blockers(position, direction, [b[0].id for b in beams], [ego, *vehicles], matrices)
    return SpotLights(
        position=position,
        direction=direction,
        color=np.tile(np.array(LOW_BEAM_COLOR), (len(beams), 1)),
        own=own,
        blocker=blocker,
        block_distance=block_distance,
    )


def beam_blockers(
    position: np.ndarray,
    direction: np.ndarray,
    owners: list[int],
    vehicles: Iterable[ActorState],
    matrices: Mapping[int, np.ndarray] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """For each beam, the nearest vehicle (not its owner) standing in it, as a cone seen from the lamp.

    Returns (N, 4) unit directions to the vehicles' centres with the cosine of the half angle their bounding sphere
    (half width and half height) covers, and (N,) the distance of their near face along that direction plus 0.3 m
    (their lit rear stays lit); :data:`NO_BLOCKER` and a half angle of zero where no vehicle stands in the beam.
    ``matrices``: the vehicles' transform matrices by actor id, when the caller has them.
    """
    n = len(position)
    blocker = np.tile(np.array([0.0, 0.0, 1.0, 1.0]), (n, 1))
    distance = np.full(n, NO_BLOCKER)
    boxes = []
    for v in vehicles:
        m = v.transform.matrix() if matrices is None else matrices[v.id]
        bb = v.bounding_box
        boxes.append((v.id, m[:3, :3] @ bb.location.to_array() + m[:3, 3], m[:3, 0], bb.extent))
    candidates = _maybe_in_beam(position, direction, boxes)
    for i in range(n):
        best = NO_BLOCKER
        for k in candidates[i]:
            vid, centre, forward, e = boxes[k]
            if vid == owners[i]:
                continue
            offset = centre - position[i]
            d = float(np.linalg.norm(offset))
            if d > BLOCKER_RANGE or d < 1e-3:
                continue
            towards = offset / d
            radius = float(np.hypot(e.y, e.z))
            half = math.asin(min(1.0, radius / d))
            # In the beam: its cone (cos 0.72 at the edge, ±44°) and the vehicle's cone overlap.
            # min/max clip as np.clip did (a NaN, which np.clip keeps, ends as no blocker either way).
            if math.acos(min(1.0, max(-1.0, float(towards @ direction[i])))) > math.acos(0.72) + half:
                continue
            # The near face: the box's half depth along the line of sight.
            c, s = abs(float(forward[:2] @ towards[:2])), math.sqrt(max(0.0, 1.0 - float(forward[:2] @ towards[:2]) ** 2))
            near = d - (e.x * c + e.y * s)
            if near < best:
                best = near
                blocker[i] = (*towards, math.cos(half))
                distance[i] = max(0.0, near) + 0.3
    return blocker, distance


#: Slack of :func:`_maybe_in_beam`'s tests (m and rad): far above the rounding of its arithmetic (near a cosine of ±1
#: an angle's rounding grows to ~1e-8 rad), far below any real distance or angle.
_PRUNE_SLACK = 1e-6


def _maybe_in_beam(position: np.ndarray, direction: np.ndarray, boxes: list) -> list[np.ndarray]:
    """For each beam, the boxes (indices, in order) that might stand in it: all but those the range or the cone
    test of :func:`beam_blockers` rejects with room to spare, worked out for every pair at once.

    The exact tests then run on these pairs alone, as before, so the blockers found do not change; about half the
    vehicles of a frame are beyond the range of a given lamp and most of the rest outside its cone.
    """
    if not boxes:
        return [np.zeros(0, np.int64)] * len(position)
    centres = np.array([b[1] for b in boxes], np.float64)
    radius = np.array([math.hypot(b[3].y, b[3].z) for b in boxes], np.float64)
    offset = centres[None, :, :] - np.asarray(position, np.float64)[:, None, :]
    d = np.sqrt((offset * offset).sum(axis=2))
    with np.errstate(divide="ignore", invalid="ignore"):
        cos = (offset * np.asarray(direction, np.float64)[:, None, :]).sum(axis=2) / d
        half = np.arcsin(np.minimum(1.0, radius[None, :] / d))
        angle = np.arccos(np.clip(cos, -1.0, 1.0))
    out = (d > BLOCKER_RANGE + _PRUNE_SLACK) | (angle > math.acos(0.72) + half + _PRUNE_SLACK)
    # d below the 1 mm the exact test skips: the cone test means nothing there, keep the pair for the exact test.
    keep = ~out | (d < 1e-3 + _PRUNE_SLACK)
    return [np.flatnonzero(row) for row in keep]


def beams_in_view(lights: SpotLights, viewproj: np.ndarray) -> SpotLights:
    """The beams whose lit region (the :data:`BEAM_BOUND` sphere) is not wholly outside one of the view's clip planes.

    ``viewproj`` is the view's world → GL clip matrix; a camera is then lit by the beams it can see the light of.
    """
    if len(lights) == 0:
        return lights
    ahead, radius = BEAM_BOUND
    centres = lights.position + lights.direction * ahead
    rows, w = viewproj[:3], viewproj[3]
    planes = np.concatenate([w + rows, w - rows])  # (6, 4): inside when ≥ 0
    norms = np.linalg.norm(planes[:, :3], axis=1)
    reach = centres @ planes[:, :3].T + planes[:, 3] + radius * norms
    keep = np.flatnonzero((reach >= 0.0).all(axis=1))
    return lights.subset(keep)
