"""The two learned baselines, written from their papers' descriptions (no pretrained weights, no torchvision).

- :class:`ADMLP` ("Rethinking the Open-Loop Evaluation of End-to-End Autonomous Driving in nuScenes", Zhai et al.
  2023, as Bench2DriveZoo trains it): an MLP from the ego's past states and the route command to future waypoints.
- :class:`TCPSmall` ("Trajectory-guided Control Prediction for End-to-end Autonomous Driving", Wu et al. 2022):
  front camera + measurements (speed, target point, command) → a trajectory branch (GRU decoding waypoints towards
  the target point) and a control branch (measurement-guided spatial attention over the image features → one of
  Think2Drive's 39 discrete actions, the expert action every clip frame records), with TCP's auxiliary speed head
  and feature distillation towards the frame's expert feature. The image encoder is a small ResNet-style CNN
  (4 stages of basic blocks, 32–256 channels) instead of TCP's ImageNet ResNet-34.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import torch
from torch import nn

from baselines.features import ADMLP_INPUT_DIM, TCP_STATE_DIM

#: Fixed input scales of the AD-MLP (metres over 2 s of history, radians, m/s, m/s², one-hot).
_ADMLP_SCALE = [10.0] * 8 + [1.0] * 4 + [10.0] + [10.0] * 3 + [1.0] * 6
#: ImageNet statistics, as TCP's ``Normalize`` uses.
IMAGE_MEAN = (0.485, 0.456, 0.406)
IMAGE_STD = (0.229, 0.224, 0.225)


@dataclass
class ADMLPConfig:
    """AD-MLP size: hidden width and future steps (each step predicts x, y, yaw)."""

    hidden: int = 512
    future_steps: int = 6

    def to_dict(self) -> dict:
        """Plain dict for checkpoints."""
        return asdict(self)


class ADMLP(nn.Module):
    """Ego history + command (22 values) → (B, future_steps, 3) waypoints [x, y, yaw] in the CARLA ego frame."""

    def __init__(self, config: ADMLPConfig | None = None) -> None:
        super().__init__()
        self.config = config or ADMLPConfig()
        h = self.config.hidden
        self.register_buffer("scale", torch.tensor(_ADMLP_SCALE, dtype=torch.float32), persistent=False)
        # Outputs in units of 10 m for x, y (waypoints reach ~30 m in 3 s) and radians for yaw.
        self.register_buffer("out_scale", torch.tensor([10.0, 10.0, 1.0]), persistent=False)
        self.net = nn.Sequential(
            nn.Linear(ADMLP_INPUT_DIM, h), nn.ReLU(inplace=True),
            nn.Linear(h, h), nn.ReLU(inplace=True),
            nn.Linear(h, self.config.future_steps * 3),
        )  # fmt: skip

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """Waypoints (B, K, 3) from inputs (B, 22)."""
        out = self.net(x / self.scale)
        return out.view(x.shape[0], self.config.future_steps, 3) * self.out_scale


@dataclass
class TCPConfig:
    """TCP-style model size and input resolution."""

    image_height: int = 144
    image_width: int = 256
    channels: tuple[int, ...] = (32, 64, 128, 256)
    future_steps: int = 4
    hidden: int = 256
    num_actions: int = 39
    feature_dim: int = 0  # expert feature length to distil (0: no feature head)
    attention_grid: tuple[int, int] = (6, 12)

    def to_dict(self) -> dict:
        """Plain dict for checkpoints."""
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> TCPConfig:
        """Inverse of :meth:`to_dict` (lists back to tuples)."""
        d = dict(d)
        d["channels"] = tuple(d["channels"])
        d["attention_grid"] = tuple(d["attention_grid"])
        return cls(**d)


class BasicBlock(nn.Module):
    """ResNet basic block: two 3×3 convolutions with batch norm and a projected shortcut when the shape changes."""

    def __init__(self, cin: int, cout: int, stride: int) -> None:
        super().__init__()
        self.body = nn.Sequential(
            nn.Conv2d(cin, cout, 3, stride, 1, bias=False), nn.BatchNorm2d(cout), nn.ReLU(inplace=True),
            nn.Conv2d(cout, cout, 3, 1, 1, bias=False), nn.BatchNorm2d(cout),
        )  # fmt: skip
        self.skip = (
            nn.Identity()
            if stride == 1 and cin == cout
            else nn.Sequential(nn.Conv2d(cin, cout, 1, stride, bias=False), nn.BatchNorm2d(cout))
        )
        self.act = nn.ReLU(inplace=True)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """Residual step."""
        return self.act(self.body(x) + self.skip(x))


class SmallResNet(nn.Module):
    """Stem (stride 2) + one basic block per stage (stride 2 each): a feature map at 1/16 of the input."""

    def __init__(self, channels: tuple[int, ...]) -> None:
        super().__init__()
        self.stem = nn.Sequential(
            nn.Conv2d(3, channels[0], 5, 2, 2, bias=False), nn.BatchNorm2d(channels[0]), nn.ReLU(inplace=True)
        )
        stages, cin = [], channels[0]
        for i, cout in enumerate(channels):
            stages.append(BasicBlock(cin, cout, 1 if i == 0 else 2))
            cin = cout
        self.stages = nn.Sequential(*stages)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """Feature map (B, C, H/16, W/16) for 4 stages."""
        return self.stages(self.stem(x))


def _mlp(*sizes: int) -> nn.Sequential:
    layers: list[nn.Module] = []
    for a, b in zip(sizes[:-1], sizes[1:], strict=True):
        layers += [nn.Linear(a, b), nn.ReLU(inplace=True)]
    return nn.Sequential(*layers)


class TCPSmall(nn.Module):
    """TCP's two branches over a small CNN; ``forward`` returns a dict of predictions."""

    def __init__(self, config: TCPConfig | None = None) -> None:
        super().__init__()
        self.config = c = config or TCPConfig()
        feat = c.channels[-1]
        self.register_buffer("mean", torch.tensor(IMAGE_MEAN).view(1, 3, 1, 1), persistent=False)
        self.register_buffer("std", torch.tensor(IMAGE_STD).view(1, 3, 1, 1), persistent=False)
        self.encoder = SmallResNet(c.channels)
        self.pool = nn.AdaptiveAvgPool2d(c.attention_grid)
        cells = c.attention_grid[0] * c.attention_grid[1]
        self.measurements = _mlp(TCP_STATE_DIM, 128, 128)
        self.speed_head = nn.Sequential(_mlp(feat, 128), nn.Linear(128, 1))
        self.join_traj = _mlp(feat + 128, c.hidden, c.hidden)
        self.decoder_traj = nn.GRUCell(input_size=4, hidden_size=c.hidden)
        self.output_traj = nn.Linear(c.hidden, 2)
        # Control branch: where to look comes from the measurements (TCP's init_att), then an action classifier.
        self.attention = nn.Sequential(_mlp(128, 128), nn.Linear(128, cells), nn.Softmax(dim=1))
        self.join_ctrl = _mlp(feat + 128, c.hidden, c.hidden)
        self.action_head = nn.Sequential(_mlp(c.hidden, c.hidden), nn.Linear(c.hidden, c.num_actions))
        self.feature_traj = nn.Linear(c.hidden, c.feature_dim) if c.feature_dim else None
        self.feature_ctrl = nn.Linear(c.hidden, c.feature_dim) if c.feature_dim else None

    def normalise(self, images: torch.Tensor) -> torch.Tensor:
        """uint8 (B, H, W, 3) RGB at any size → normalised float (B, 3, h, w) at the model's input size."""
        x = images.permute(0, 3, 1, 2).float() / 255.0
        size = (self.config.image_height, self.config.image_width)
        if tuple(x.shape[-2:]) != size:
            x = nn.functional.interpolate(x, size=size, mode="bilinear", align_corners=False, antialias=True)
        return (x - self.mean) / self.std

    def forward(self, images: torch.Tensor, state: torch.Tensor, target_point: torch.Tensor) -> dict[str, torch.Tensor]:
        """Predictions from uint8 images (B, H, W, 3), state (B, 9) and target point (B, 2)."""
        fmap = self.pool(self.encoder(self.normalise(images)))  # (B, C, gh, gw)
        flat = fmap.flatten(2)  # (B, C, cells)
        emb = flat.mean(dim=2)
        meas = self.measurements(state)
        out: dict[str, torch.Tensor] = {"pred_speed": self.speed_head(emb).squeeze(1)}
        z = self.join_traj(torch.cat([emb, meas], dim=1))
        joined_traj = z
        x = torch.zeros(z.shape[0], 2, dtype=z.dtype, device=z.device)
        waypoints = []
        for _ in range(self.config.future_steps):
            z = self.decoder_traj(torch.cat([x, target_point], dim=1), z)
            x = x + self.output_traj(z)
            waypoints.append(x)
        out["pred_wp"] = torch.stack(waypoints, dim=1)
        att = self.attention(meas).unsqueeze(1)  # (B, 1, cells)
        attended = (flat * att).sum(dim=2)
        j_ctrl = self.join_ctrl(torch.cat([attended, meas], dim=1))
        out["action_logits"] = self.action_head(j_ctrl)
        if self.feature_traj is not None and self.feature_ctrl is not None:
            out["feature_traj"] = self.feature_traj(joined_traj)
            out["feature_ctrl"] = self.feature_ctrl(j_ctrl)
        return out
