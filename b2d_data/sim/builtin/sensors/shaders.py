"""GLSL sources of the camera renderer (kept as Python strings so they ship inside the package).

The scene program draws into four colour attachments at once: 0 = RGBA8 colour, 1 = R32F planar depth (metres
along the optical axis; R8UI uint8 metres, rounded as the depth PNG stores them, when ``DEPTH8``), 2 = R8UI semantic
tag and instance id packed as RGBA8UI (tag, id low byte, id high byte, 255: the bytes of an instance PNG pixel, so
the read-back is the image the PNG encoder takes). It is compiled once per material and weather
variant (``#define`` switches) because a software rasteriser runs every branch of a shader for every pixel:
specialised programs keep each pixel's work to what its material and the weather need. The sky program fills the
pixels no geometry covered with the sky colour, a depth of :data:`SKY_DEPTH` and the sky tag.

What varies smoothly over a triangle is lit per vertex (ambient light, the sun's diffuse light on flat or smooth
faces, sky reflections, other vehicles' low beams, street-lamp pools on all but facades); what does not is lit per
pixel: the sun's shadow (``SHADOW``: a shadow map drawn once per frame, one filtered lookup a pixel) and at night
(``NIGHT``) the cameras' own vehicle's low beam, whose cone and fall-off a 2 m road strip or a 30 m facade cannot
carry in its corners. Fog (UE4's exponential height fog, :func:`lighting.fog_amount`) is per vertex where the
triangles are small against its change (:func:`vertex_fog`: roads, thin fog, far tiles), else per pixel. Static
tiles wholly beyond :data:`DISTANT_FROM` are drawn ``distant``: at night their own beam, pools and fog come per
vertex (their triangles are small on screen, and a software rasteriser pays for every per-pixel light on them).
With ``AIRLIGHT`` the own low beam also lights the fog between the camera and each pixel (per vertex).
Every instruction a pixel runs costs llvmpipe about 2 ms a frame of the full rig (1600×900 ×7 on one thread):
work that can move to the vertices does. On a software rasteriser (``software`` variants) more moves, at some cost
in image quality: the own low beam on the materials of :data:`SOFTWARE_PER_VERTEX`, the fog on all but facades by
day in any fog and on facades too at night (:func:`vertex_fog`), and the low beam's glow in the fog with
:data:`SOFTWARE_AIRLIGHT_SAMPLES` (the renderer also takes the nearest texel of the sharp sun's shadow map there,
not of an overcast sky's coarse one); without ``software`` every source is the hardware GPU's, unchanged. Only the
colour output depends on any of this: depth, tag and instance id come from the geometry alone.
"""

from __future__ import annotations

from b2d_data.sim.builtin.sensors.vehicle_lights import MAX_LIGHTS

#: Depth written for sky pixels: CARLA's far plane (1000 m).
SKY_DEPTH = 1000.0
#: CARLA semantic tag of sky pixels.
SKY_TAG = 11
#: Samples along a camera ray of the low beam's light in the fog (``AIRLIGHT``).
AIRLIGHT_SAMPLES = 8
#: The same on a software rasteriser, where every vertex's samples cost CPU (``software`` variants).
SOFTWARE_AIRLIGHT_SAMPLES = 4
#: Farthest distance (m) from the camera at which the ego's low beam still lights the fog.
AIRLIGHT_REACH = 45.0

# Lamp colour and strength of the street-lamp pools (the light-map's 1.0), shared by surfaces and fog.
_LAMPS = """
const vec3 LAMP_LIGHT = vec3(1.0, 0.82, 0.58) * 0.45;
"""

# The street lamps' light on the ground at p (the light-map), fading out over the first 6 m above it.
_LAMP_POOL = """
float lamp_pool(vec3 p) {
    vec2 luv = (p.xy - u_lightmap_rect.xy) * u_lightmap_rect.zw;
    return textureLod(u_lightmap, luv, 0.0).r * clamp(1.0 - (p.z - 0.5) / 6.0, 0.0, 1.0);
}
"""

# Fog as UE4's exponential height fog: the optical depth along the ray from the camera to p, skipping the first
# u_fog_start metres, of a density u_fog_density · exp(−u_fog_falloff · (z − u_fog_base)) (lighting.fog_amount).
_FOG = """
uniform float u_fog_density;
uniform float u_fog_falloff;
uniform float u_fog_start;
uniform float u_fog_base;
float fog_density_at(float z) {
#if FALLOFF
    return u_fog_density * exp(clamp(-u_fog_falloff * (z - u_fog_base), -80.0, 80.0));
#else
    return u_fog_density;
#endif
}
float fog_amount(vec3 cam, vec3 p) {
    vec3 d = p - cam;
    float len = length(d);
    float inside = max(len - u_fog_start, 0.0);
#if FALLOFF
    float slope = d.z / max(len, 1e-4);
    float x = u_fog_falloff * slope * inside;
    float g = abs(x) > 1e-4 ? (1.0 - exp(-x)) / x : 1.0 - 0.5 * x;
    return 1.0 - exp(-fog_density_at(cam.z + slope * min(u_fog_start, len)) * inside * g);
#else
    // Without a height falloff (every Bench2Drive weather) the density is the same everywhere.
    return 1.0 - exp(-u_fog_density * inside);
#endif
}
// The same without a height falloff, from the distance to the camera alone.
float fog_of_distance(float len) {
    return 1.0 - exp(-u_fog_density * max(len - u_fog_start, 0.0));
}
"""

# The ego's low beam scattered towards the camera by the fog between it and p: the integral of density × beam ×
# transmittance, sampled more densely near the camera where the beam is strongest. It varies slowly over the image
# (a glow), so it is computed per vertex (and per sky-grid vertex).
_AIRLIGHT = """
vec3 airlight(vec3 cam, vec3 p) {
    // Light 0 is the ego's low beam (the renderer compiles AIRLIGHT only then).
    vec3 d = p - cam;
    float len = min(length(d), AIRLIGHT_REACH);
    vec3 dir = normalize(d);
    vec3 sum = vec3(0.0);
    for (int k = 0; k < AIRLIGHT_SAMPLES; ++k) {
        float s = (float(k) + 0.5) / float(AIRLIGHT_SAMPLES);
        float t = len * s * s;
        vec3 x = cam + dir * t;
        float seen = step(u_fog_start, t) * (1.0 - fog_amount(cam, x));
        sum += spot_light(0, x, vec3(0.0), false) * fog_density_at(x.z) * seen * (2.0 * s * len);
    }
    // Isotropic scattering over the sample spacing (1 / AIRLIGHT_SAMPLES), times the fog's albedo.
    return sum * (0.35 / float(AIRLIGHT_SAMPLES)) * u_beams;
}
"""

# Low beams (vehicle_lights.SpotLights): position, unit direction, RGB strength. A beam lights a cone about ±35°
# wide, cut off just above the lamp's horizon as a dipped beam is aimed (a tenth spills above it), and falls off as
# 1 / (1 + d²/R²): the inverse square law away from the lamp, capped near it. ``surface``: the light on a face with
# normal n (its facing term), else on the fog. The cameras' own vehicle's beam (OWN: light 0) is lit per pixel, the
# other vehicles' beams per vertex: each light costs every pixel of a software rasteriser some 6 ns, and the other
# beams fall on the road (2 m strips) from afar. NLIGHTS is a compile-time count (the renderer pads the lights to
# the next of a few sizes with dark ones), so that the loop unrolls into straight uniform reads.
_SPOTS = """
uniform vec4 u_light_pos[MAX_LIGHTS];
uniform vec4 u_light_dir[MAX_LIGHTS];
uniform vec4 u_light_col[MAX_LIGHTS];
uniform vec4 u_light_block[MAX_LIGHTS];  // the vehicle standing in the beam: direction, cos of its half angle
const float LOW_BEAM_REACH = 18.0;
vec3 spot_light(int i, vec3 x, vec3 n, bool surface) {
    // Linear ramps, not smoothstep: a software rasteriser pays for every instruction of every light at every pixel.
    vec3 r = x - u_light_pos[i].xyz;
    float d2 = dot(r, r);
    float inv = inversesqrt(d2 + 1e-4);
    float cone = clamp((dot(r, u_light_dir[i].xyz) * inv - 0.72) * (1.0 / 0.22), 0.0, 1.0);  // full within ±20°
    float below = clamp((0.06 - r.z * inv) * (1.0 / 0.07), 0.1, 1.0);  // cut off 1°-3.5° above the lamp's horizon
    // Behind the vehicle standing in the beam (farther than u_light_pos.w, within its cone) the lamp is hidden. The
    // own beam with no vehicle in it (OWN_BLOCKED 0) skips the test, whose result would be 0 at every pixel.
    float hidden = 0.0;
    if (OWN == 0 || i != 0 || OWN_BLOCKED != 0) {
        vec4 b = u_light_block[i];
        hidden = clamp((d2 * inv - u_light_pos[i].w) * 2.0, 0.0, 1.0) * clamp((dot(r, b.xyz) * inv - b.w) * 400.0, 0.0, 1.0);
    }
    float w = cone * below * (1.0 - hidden) / (1.0 + d2 * (1.0 / (LOW_BEAM_REACH * LOW_BEAM_REACH)));
    if (surface) {
        // Lambert's cosine, lifted at grazing light: asphalt and paint send part of a low beam back towards it.
        float c = -dot(n, r) * inv;
        w *= clamp(c * 20.0 + 0.4, 0.0, 1.0) * (0.45 + 0.55 * max(c, 0.0));
    }
    return u_light_col[i].rgb * w;
}
"""

_SCENE_VERTEX = """
uniform mat4 u_viewproj;
uniform vec3 u_cam_pos;
uniform vec3 u_cam_fwd;
uniform vec3 u_sun_dir;
uniform vec3 u_sun_color;
uniform vec3 u_ambient_sky;
uniform vec3 u_ambient_ground;
uniform vec3 u_sky_zenith;
uniform vec3 u_sky_horizon;
uniform float u_wetness;
uniform float u_night;
uniform vec3 u_fog_color;
FOG_FUNCTIONS
#if NIGHT
uniform float u_beams;
SPOT_FUNCTIONS
#if VBEAMS
out vec3 v_beams;
#endif
#endif
#if AIRLIGHT
AIRLIGHT_FUNCTION
out vec3 v_air;
#endif
#if VFOG && NIGHT
out float v_fog;
#endif
#if VPOOL
uniform sampler2D u_lightmap;
uniform vec4 u_lightmap_rect;
out float v_pool;
LAMP_POOL
#endif
#if SHADOW
uniform mat4 u_shadow_matrix;   // world -> shadow-map texture coordinates and depth, all in [0, 1]
uniform float u_shadow_offset;  // metres along the normal: keeps a lit face from shadowing itself
uniform float u_shadow_strength;
out vec3 v_shadow;
out vec3 v_sun;
#endif
in vec3 in_pos;
in vec3 in_normal;
in vec4 in_color;
in uvec2 in_ids;
out vec3 v_pos;
out vec3 v_color;
out float v_depth;
flat out uvec2 v_ids;
#if NIGHT
out vec3 v_nrm;
out vec3 v_albedo;
#endif
#if MAT == 2
out vec3 v_alt;
out vec2 v_facade;
flat out float v_wall;
#if SHADOW
out vec3 v_alt_sun;
#endif
#elif MAT == 1 && WET
out vec3 v_alt;
out vec2 v_xy;
#if SHADOW
out vec3 v_alt_sun;
#endif
#endif

vec3 shade(vec3 albedo, vec3 ambient, vec3 sunlit, vec3 n, vec3 v, float gloss, float mirror, out vec3 sun) {
    // Diffuse light, plus for glossy materials a Fresnel-weighted reflection of the sky (dimmed by ``mirror``:
    // streets reflect buildings, not only sky) and a sun highlight. ``sun``: the part the sun gives, which a
    // shadow takes away.
    vec3 col = albedo * (ambient + sunlit);
    sun = albedo * sunlit;
    if (gloss > 0.0) {
        vec3 r = reflect(-v, n);
        float a = (0.04 + 0.96 * pow(1.0 - max(dot(n, v), 0.0), 5.0)) * gloss;
        vec3 sky = mix(u_sky_horizon, u_sky_zenith, sqrt(clamp(r.z, 0.0, 1.0))) * mirror;
        vec3 highlight = u_sun_color * pow(max(dot(n, normalize(u_sun_dir + v)), 0.0), 60.0) * gloss * 1.5;
        col = col * (1.0 - a) + sky * a + highlight;
        sun = sun * (1.0 - a) + highlight;
    }
    return col;
}

void main() {
    vec3 p = in_pos;
    vec3 to_cam = u_cam_pos - p;
    vec3 v = to_cam / max(length(to_cam), 1e-4);
    vec3 n = normalize(in_normal);
    n = dot(n, v) < 0.0 ? -n : n;
    vec3 albedo = in_color.rgb;
    vec3 ambient = mix(u_ambient_ground, u_ambient_sky, n.z * 0.5 + 0.5);
    vec3 sunlit = u_sun_color * max(dot(n, u_sun_dir), 0.0);
    vec3 sun;
#if MAT == 3
    vec3 col = shade(albedo, ambient, sunlit, n, v, 0.7, 1.0, sun);
#elif MAT == 6
    vec3 col = shade(albedo, ambient, sunlit, n, v, 0.12, 1.0, sun);
#else
    vec3 col = shade(albedo, ambient, sunlit, n, v, 0.0, 0.0, sun);
#endif
#if MAT == 4
    col += albedo * (0.25 + 1.6 * u_night);
#elif MAT == 1 && WET
    vec3 wet_sun;
    vec3 wet = shade(albedo * 0.45, ambient, sunlit, n, v, 0.6, 0.45, wet_sun);
    col = mix(col, wet, u_wetness);
    sun = mix(sun, wet_sun, u_wetness);
    v_alt = wet;
#if SHADOW
    v_alt_sun = wet_sun;
#endif
    v_xy = p.xy * 0.029;
#elif MAT == 2
    vec3 window_sun;
    v_alt = shade(vec3(0.11, 0.14, 0.18), ambient, sunlit, n, v, 0.45, 1.0, window_sun);
#if SHADOW
    v_alt_sun = window_sun;
#endif
    float side = abs(n.x) > abs(n.y) ? p.y : p.x;
    v_facade = vec2(side / 3.1, p.z / 3.3);
    v_wall = abs(n.z) < 0.5 ? 1.0 : 0.0;
#endif
#if SHADOW
    // Faces the sun does not reach (walls at noon, the far side of everything) keep their windows' sky and highlight.
    float faces_sun = sun.r + sun.g > 0.004 ? 1.0 : 0.0;
#endif
#if VFOG
    float fog = fog_amount(u_cam_pos, p);
#if NIGHT
    v_fog = fog;
#else
    // By day the fog is the last step of the colour: it goes into every interpolated colour (a shadow then takes
    // the fogged sun's share).
    col = mix(col, u_fog_color, fog);
    sun *= 1.0 - fog;
#if MAT == 1 && WET
    v_alt = mix(v_alt, u_fog_color, fog);
#if SHADOW
    v_alt_sun *= 1.0 - fog;
#endif
#endif
#endif
#endif
#if SHADOW
    // What the sun gives that a full shadow takes away: the shadow's strength, faded out over the last tenth of the
    // map towards its edge (beyond it every fragment is sunlit). Per vertex: the fragment only scales it by the
    // shadow map's result, one filtered lookup.
    vec3 s = (u_shadow_matrix * vec4(p + n * u_shadow_offset, 1.0)).xyz;
    vec2 edge = abs(s.xy - 0.5) * 2.0;
    float keep = faces_sun * u_shadow_strength * (1.0 - smoothstep(0.9, 1.0, max(edge.x, edge.y)));
    v_sun = sun * keep;
#if MAT == 2 || (MAT == 1 && WET)
    v_alt_sun *= keep;
#endif
    v_shadow = vec3(s.xy, min(s.z, 1.0));
#endif
#if NIGHT
    v_nrm = n;
    v_albedo = albedo;
    vec3 others = vec3(0.0);
#if MAT != 2
    // Not on facades: a wall is two triangles, whose corners cannot carry a beam's pool.
    for (int i = OWN; i < NLIGHTS; ++i) {
        others += spot_light(i, p, n, true);
    }
#endif
#if VPOOL
    // Lamp pools per vertex: a pool is a Gaussian of 7 m, which roads' 2-4 m and sidewalks' 2 m triangles carry.
    v_pool = lamp_pool(p);
#endif
#if VBEAMS
    v_beams = others * u_beams;
#else
    // Where the pixel keeps the vertex's albedo, the other beams' light is part of the interpolated colour.
    col += albedo * others * u_beams;
#endif
#endif
#if AIRLIGHT
    v_air = airlight(u_cam_pos, p);
#endif
    v_pos = p;
    v_color = col;
    v_depth = dot(p - u_cam_pos, u_cam_fwd);
    v_ids = in_ids;
    gl_Position = u_viewproj * vec4(p, 1.0);
}
"""

_SCENE_FRAGMENT = """
uniform float u_puddles;
uniform float u_wetness;
uniform float u_night;
uniform sampler2D u_noise;
uniform vec3 u_cam_pos;
uniform vec3 u_fog_color;
FOG_FUNCTIONS
#if SHADOW
uniform sampler2DShadow u_shadow_map;
in vec3 v_shadow;
in vec3 v_sun;
#endif
#if NIGHT
uniform sampler2D u_lightmap;
uniform vec4 u_lightmap_rect;
uniform float u_lamp_glow;
uniform float u_beams;
LAMP_CONSTANTS
SPOT_FUNCTIONS
in vec3 v_nrm;
in vec3 v_albedo;
#if VBEAMS
in vec3 v_beams;
#endif
#endif
#if AIRLIGHT
in vec3 v_air;
#endif
#if NIGHT || FALLOFF
in vec3 v_pos;
#elif !VFOG
uniform vec4 u_pixel_ray;  // 1/fx, 1/fy, cx, cy of the camera's K
#endif
#if VFOG && NIGHT
in float v_fog;
#endif
#if VPOOL
in float v_pool;
#endif
in vec3 v_color;
in float v_depth;
flat in uvec2 v_ids;
#if MAT == 2
in vec3 v_alt;
in vec2 v_facade;
flat in float v_wall;
#if SHADOW
in vec3 v_alt_sun;
#endif
#elif MAT == 1 && WET
in vec3 v_alt;
in vec2 v_xy;
#if SHADOW
in vec3 v_alt_sun;
#endif
#endif
layout(location = 0) out vec4 f_color;
DEPTH_OUT
layout(location = 2) out uvec4 f_labels;
layout(location = 3) out uint f_tag;

#if SHADOW
float sun_shadow() {
    // Share of the sun's light (v_sun, already scaled by the shadow's strength) this fragment loses: 0 in the sun,
    // 1 in full shadow. The comparison sampler filters 2×2 texels: an anti-aliased edge, blurred over a penumbra by
    // the coarser map of an overcast sky.
    return 1.0 - texture(u_shadow_map, v_shadow);
}
#endif

#if NIGHT
LAMP_POOL

vec3 beams(vec3 p, vec3 n) {
#if VBEAMS
    vec3 others = v_beams;
#else
    vec3 others = vec3(0.0);  // in v_color (or, on facades, none)
#endif
#if OWN
    return others + spot_light(0, p, n, true) * u_beams;
#else
    return others;
#endif
}
#endif


void main() {
    vec3 col = v_color;
#if SHADOW
    // No branch around the lookup for faces the sun does not reach (their v_sun is 0): a software rasteriser runs
    // both sides of a branch.
    float shadow = sun_shadow();
    col -= v_sun * shadow;
#endif
#if NIGHT
    vec3 albedo = v_albedo;
#endif
#if MAT == 2
    vec2 f = fract(v_facade);
    float win = v_wall * step(1.0, v_facade.y) * step(0.22, f.x) * step(f.x, 0.78) * step(0.3, f.y) * step(f.y, 0.82);
    vec3 window = v_alt;
#if SHADOW
    window -= v_alt_sun * shadow;
#endif
#if NIGHT
    vec2 cell = floor(v_facade);
    float lit = step(0.72, fract(sin(dot(cell, vec2(12.9898, 78.233))) * 43758.5453));
    window += vec3(1.0, 0.78, 0.45) * 0.32 * u_night * lit;
    albedo = mix(albedo, vec3(0.11, 0.14, 0.18), win);
#endif
    col = mix(col, window, win);
#elif MAT == 1 && WET
    float blob = texture(u_noise, v_xy).g;
    float puddle = smoothstep(0.66, 0.72, blob + 0.25 * u_puddles) * u_puddles;
    vec3 wet = v_alt;
#if SHADOW
    wet -= v_alt_sun * shadow;
#endif
    col = mix(col, wet, puddle);
#if NIGHT
    float water = max(u_wetness, puddle);
    albedo *= mix(1.0, 0.45, water);
#endif
#endif
    vec3 fog_color = u_fog_color;
#if NIGHT
#if VPOOL
    float pool = v_pool;
#else
    float pool = lamp_pool(v_pos);
#endif
    col += albedo * (LAMP_LIGHT * pool * u_night + beams(v_pos, normalize(v_nrm)));
#if MAT == 1 && WET
    // A wet road mirrors the lamp above a pool: a glossy sheen where the dry road only scatters.
    col += LAMP_LIGHT * pool * u_night * 0.35 * water;
#endif
    // A shoulder above 0.75, as a camera's response has: surfaces in a low beam a few metres away keep their hue.
    col /= 1.0 + max(col - 0.75, 0.0);
    // Street lamps light the fog around them.
    fog_color += LAMP_LIGHT * u_lamp_glow * pool;
#endif
#if VFOG && NIGHT
    col = mix(col, fog_color, v_fog);
#elif VFOG
    // (by day the vertex shader fogged the colours)
#elif NIGHT || FALLOFF
    col = mix(col, fog_color, fog_amount(u_cam_pos, v_pos));
#else
    // The distance to the camera from the planar depth and the pixel's ray (gl_FragCoord is the image's u, v): the
    // same value as length(v_pos - u_cam_pos), without three interpolated inputs, which a software rasteriser pays
    // for at every pixel.
    vec2 ray = (gl_FragCoord.xy - u_pixel_ray.zw) * u_pixel_ray.xy;
    col = mix(col, fog_color, fog_of_distance(v_depth * sqrt(1.0 + dot(ray, ray))));
#endif
#if AIRLIGHT
    col += v_air;
#endif
    f_color = vec4(clamp(col, 0.0, 1.0), 1.0);
    f_depth = depth_out(v_depth);
    f_labels = uvec4(v_ids.x, v_ids.y & 255u, (v_ids.y >> 8) & 255u, 255u);
    f_tag = v_ids.x;
}
"""


#: Light counts a scene program is compiled for; a frame's lights are padded to the next one.
LIGHT_COUNTS = (0, 1, 2, 3, 4, 6, 8)
assert LIGHT_COUNTS[-1] == MAX_LIGHTS


def light_count(n: int) -> int:
    """The compiled light count that holds ``n`` lights."""
    return next(c for c in LIGHT_COUNTS if c >= min(n, MAX_LIGHTS))


#: Fog extinction (per metre) up to which every material but facades is fogged per vertex (weathers 0, 1, 5, 7, 18,
#: 19, 26): on a 30 m triangle next to the camera the per-vertex distance is off by up to ~10 m, 1 % of fog here.
THIN_FOG = 0.002
#: Materials a software rasteriser lights with the own low beam per vertex, near or far (``software`` variants;
#: scene_mesh.Material values): glass, lamps and paint, the actors' faces of a metre or two. Not ground, foliage or
#: facades, whose triangles reach 18-50 m, across which the beam's cone would show the corners (compare_renders'
#: night weather: up to 100 levels), nor roads: interpolated between corners 2-4 m apart the beam's peak sinks, and
#: the road ahead at night drops below half of noon's luma (weather_gallery, Town10HD weather 21: 0.43).
SOFTWARE_PER_VERTEX: frozenset[int] = frozenset({3, 4, 6})


def vertex_fog(material: int, falloff: bool, thin_fog: bool, distant: bool = False, fog_start: bool = False,
               software: bool = False, fogless: bool = False, night: bool = False) -> bool:  # fmt: skip
    """Whether a scene program fogs per vertex (its fog amount interpolated between the triangle's corners).

    Roads always (99 % of their triangles are under 4.3 m: the interpolated amount stays within about one level of
    the per-pixel one even in the densest fog); every other material but facades (a wall is two triangles whose
    corners lie metres farther from the camera than its middle) when the fog is thin (``thin_fog``) or the
    triangles are far from the camera (``distant``); never when the fog thins with height (``falloff``) or starts
    some way out (``fog_start``: the amount's kink there would be smeared over a triangle, up to 28 levels on a
    road in fog 60 from 10 m). A software rasteriser pays ~5 ns a pixel for the per-pixel fog; with ``software`` it
    fogs every material but facades per vertex in any fog as well (in compare_renders' poses under weathers 11, 12
    and 22, fog 50-60: RGB within 5 levels of the per-pixel fog, 0.1-0.2 % of values off by more than 2); facades
    too at ``night`` (the fragment applies the interpolated amount last, windows included; weathers 20 and 22: within
    4 levels, 0.06 % of values off by more than 2) or where there is no fog at all (``fogless``: a fog amount of
    exactly 0 wherever it is computed, so the pixels stay the same; by day the vertex shader fogs the colours, and
    the facades' window colour is not among them).
    """
    if software and fogless:
        return True
    if falloff or fog_start:
        return False
    return int(material) == 1 or (software and night) or ((thin_fog or distant or software) and int(material) != 2)


#: Static tiles whose every point lies farther than this (m) from the camera are drawn ``distant``: at night every
#: material but facades gets its lamp pools, fog and the own low beam per vertex there. Beyond 30 m the beam's cone
#: is over 20 m wide and its fall-off slow, a pool is a 7 m Gaussian and the fog nearly linear across a triangle of
#: a few metres, while a software rasteriser pays for every per-pixel light on the many small far triangles.
DISTANT_FROM = 30.0


def _header(material: int, night: bool, wet: bool, shadow: bool = False, airlight: bool = False, falloff: bool = False,
            lights: int = 0, own: bool = False, own_blocked: bool = True, thin_fog: bool = False,
            distant: bool = False, fog_start: bool = False, software: bool = False, fogless: bool = False
            ) -> str:  # fmt: skip
    distant = distant and int(material) != 2  # facades are lit alike near and far
    # Distant: the own beam joins the other beams in the vertex shader's loop (light 0 first), the pools come per
    # vertex as on roads.
    # On a software rasteriser the own beam is per vertex on actors too (RGB off by up to 28 levels where the cone's
    # edge crosses a car's face).
    own = own and not distant and not (software and int(material) in SOFTWARE_PER_VERTEX)
    # Lamp pools (7 m Gaussians) per vertex on every material but facades, whose two triangles a wall cannot carry
    # a pool on: per pixel they cost a software rasteriser ~60 ms a frame of the rig at night.
    pool = night and int(material) != 2
    return (
        f"#version 330\n#define MAT {int(material)}\n#define NIGHT {int(night)}\n#define WET {int(wet)}\n"
        f"#define SHADOW {int(shadow)}\n#define AIRLIGHT {int(airlight)}\n"
        f"#define FALLOFF {int(falloff)}\n#define NLIGHTS {int(lights)}\n#define OWN {int(own)}\n"
        f"#define OWN_BLOCKED {int(own_blocked)}\n"
        # The other beams reach the fragment as their own input only on a wet road (its albedo changes per pixel).
        f"#define VBEAMS {int(int(material) == 1 and wet)}\n"
        f"#define MAX_LIGHTS {MAX_LIGHTS}\n"
        f"#define VFOG {int(vertex_fog(material, falloff, thin_fog, distant, fog_start, software, fogless, night))}\n"
        f"#define VPOOL {int(pool)}\n"
        f"#define AIRLIGHT_SAMPLES {_airlight_samples(software)}\n#define AIRLIGHT_REACH {AIRLIGHT_REACH:.1f}\n"
    )


def _airlight_samples(software: bool) -> int:
    return SOFTWARE_AIRLIGHT_SAMPLES if software else AIRLIGHT_SAMPLES


def _functions(source: str) -> str:
    """Paste the shared GLSL functions into a shader source."""
    return (source.replace("FOG_FUNCTIONS", _FOG).replace("LAMP_CONSTANTS", _LAMPS).replace("SPOT_FUNCTIONS", _SPOTS)
            .replace("AIRLIGHT_FUNCTION", _AIRLIGHT).replace("LAMP_POOL", _LAMP_POOL))  # fmt: skip


def scene_vertex(material: int, night: bool, wet: bool, *, shadow: bool = False, airlight: bool = False,
                 falloff: bool = False, lights: int = 0, own: bool = False, own_blocked: bool = True,
                 thin_fog: bool = False, distant: bool = False, fog_start: bool = False,
                 software: bool = False, fogless: bool = False) -> str:  # fmt: skip
    """The scene vertex shader specialised for one material and weather variant (``software``: see
    :func:`scene_fragment`)."""
    header = _header(material, night, wet, shadow, airlight, falloff, lights, own, own_blocked, thin_fog, distant,
                     fog_start, software, fogless)  # fmt: skip
    return header + _functions(_SCENE_VERTEX)


# The depth target: float metres, or the uint8 the depth PNG stores. OpenCV's float → uint8 conversion is
# saturate_cast<uchar>(cvRound(v)): round half to even, clip to [0, 255], and 0 for NaN, ±inf and values beyond
# the int32 range (cvRound returns INT_MIN for them); the same float rounded here gives the same byte.
_DEPTH_FLOAT = """layout(location = 1) out float f_depth;
float depth_out(float d) { return d; }
"""
_DEPTH8 = """layout(location = 1) out uint f_depth;
uint depth_out(float d) {
    float r = roundEven(d);
    bool outside = isnan(d) || isinf(d) || r >= 2147483648.0 || r < -2147483648.0;
    return outside ? 0u : uint(clamp(r, 0.0, 255.0));
}
"""


# One target instead of four (``packed``): the shading writes the four outputs into globals, then one RG32UI output
# holds them all (colour bytes and tag; id and depth byte), and UNPACK_COMPUTE spreads them over the four targets.
# Every fragment then costs one 8-byte write instead of four (10 bytes): an H100 rasterises on few SMs, and the four
# writes were a third of a camera's GPU time.
_PACKED_OUT = """layout(location = 0) out uvec2 f_packed;
vec4 f_color;
uvec4 f_labels;
uint f_tag;
""" + _DEPTH8.replace("layout(location = 1) out uint f_depth;", "uint f_depth;")
_PACKED_MAIN = """
void main() {
    shade();
    // An RGBA8 target's conversion: clamp, scale by 255, round to nearest (GL lets a GPU round either way near
    // halves: an H100's target differs from this by one level on 3-4 % of values, a far smaller change than JPEG's).
    uvec3 c = uvec3(floor(clamp(f_color.rgb, 0.0, 1.0) * 255.0 + 0.5));
    f_packed = uvec2(c.r | (c.g << 8) | (c.b << 16) | ((f_labels.r & 255u) << 24),
                     (f_labels.g & 255u) | ((f_labels.b & 255u) << 8) | (f_depth << 16));
}
"""


def _fragment(source: str, depth8: bool, packed: bool = False) -> str:
    if packed:
        if not depth8:
            raise ValueError("packed targets hold uint8 depth only")
        outputs = "\n".join(line for line in source.splitlines() if not line.startswith("layout(location"))
        return outputs.replace("DEPTH_OUT", _PACKED_OUT).replace("void main()", "void shade()") + _PACKED_MAIN
    return source.replace("DEPTH_OUT", _DEPTH8 if depth8 else _DEPTH_FLOAT)


def scene_fragment(material: int, night: bool, wet: bool, depth8: bool = False, packed: bool = False, *,
                   shadow: bool = False, airlight: bool = False, falloff: bool = False, lights: int = 0,
                   own: bool = False, own_blocked: bool = True, thin_fog: bool = False,
                   distant: bool = False, fog_start: bool = False, software: bool = False,
                   fogless: bool = False) -> str:  # fmt: skip
    """The scene fragment shader for one material and weather variant (``depth8``: uint8 metres, not float;
    ``packed``: one RG32UI output, see :data:`UNPACK_COMPUTE`; ``shadow``: the sun's shadow map; ``airlight``: the
    low beam lights the fog; ``falloff``: the fog thins with height; ``lights``: the number of low beams, one of
    :data:`LIGHT_COUNTS`; ``own``: light 0 is the cameras' own beam, lit per pixel; ``own_blocked``: a vehicle
    stands in it; ``thin_fog``: the fog is thin enough to fog every material but facades per vertex,
    :func:`vertex_fog`; ``distant``: triangles beyond :data:`DISTANT_FROM`, lit per vertex at night; ``fog_start``:
    the fog starts some way out; ``software``: the cheaper variant for a software rasteriser, see
    :data:`SOFTWARE_AIRLIGHT_SAMPLES`, :data:`SOFTWARE_PER_VERTEX` and :func:`vertex_fog`; without it the source is
    the hardware GPU's; ``fogless``: no fog at all, used by the software variant only)."""
    header = _header(material, night, wet, shadow, airlight, falloff, lights, own, own_blocked, thin_fog, distant,
                     fog_start, software, fogless)  # fmt: skip
    return header + _fragment(_functions(_SCENE_FRAGMENT), depth8, packed)


_SKY_VERTEX = """
uniform mat3 u_cam_rot;   // OpenCV camera axes -> world
uniform vec4 u_intrinsic; // fx, fy, cx, cy
uniform vec2 u_viewport;  // width, height in pixels
uniform vec3 u_sky_zenith;
uniform vec3 u_sky_horizon;
uniform vec3 u_sun_dir;
uniform vec3 u_sun_color;
uniform float u_cloudiness;
uniform vec3 u_fog_color;
uniform vec3 u_cam_pos;
uniform sampler2D u_noise;
FOG_FUNCTIONS
#if AIRLIGHT
uniform float u_beams;
SPOT_FUNCTIONS
AIRLIGHT_FUNCTION
#endif
in vec2 in_xy;
out vec3 v_color;
void main() {
    // The sky is a screen-covering grid at the far plane: its colour is computed per grid vertex (the sky varies
    // smoothly) and only pixels no geometry covered are filled, so the per-pixel cost is a colour copy.
    vec2 pix = (in_xy * 0.5 + 0.5) * u_viewport;  // NDC y = 2·row/H − 1: pix.y is the image row
    vec3 ray = vec3((pix.x - u_intrinsic.z) / u_intrinsic.x, (pix.y - u_intrinsic.w) / u_intrinsic.y, 1.0);
    vec3 d = normalize(u_cam_rot * ray);
    float e = d.z;
    vec3 col = e >= 0.0 ? mix(u_sky_horizon, u_sky_zenith, sqrt(e)) : u_sky_horizon * (1.0 + 0.6 * e);
    float sun = max(dot(d, u_sun_dir), 0.0);
    col += u_sun_color * (pow(sun, 64.0) * 1.5 * (1.0 - u_cloudiness) + pow(sun, 8.0) * 0.25);
#if CLOUDS
    vec2 uv = d.xy / (max(e, 0.0) + 0.08) * 0.11;
    float nz = textureLod(u_noise, uv, 0.0).g * 0.7 + textureLod(u_noise, uv * 3.1 + 0.37, 0.0).r * 0.3;
    float cover = smoothstep(1.0 - u_cloudiness, 1.2 - 0.6 * u_cloudiness, nz + 0.3 * u_cloudiness);
    // Clouds are white where the sky is lit; at night only the glow of the town below lights them.
    float lit = clamp(u_sky_horizon.g * 1.4, 0.1, 1.0);
    vec3 cloud = mix(u_sky_horizon, vec3(lit), 0.55) * (0.5 + 0.5 * (1.0 - u_cloudiness)) * (0.8 + 0.3 * nz);
    col = mix(col, cloud, cover * smoothstep(0.0, 0.1, e));
#endif
    // The sky's fog: the height fog along 400 m of the ray near the horizon, less towards the zenith.
    v_color = mix(col, u_fog_color, fog_amount(u_cam_pos, u_cam_pos + d * (400.0 / (abs(e) * 6.0 + 1.0))));
#if AIRLIGHT
    v_color += airlight(u_cam_pos, u_cam_pos + d * AIRLIGHT_REACH);
#endif
    gl_Position = vec4(in_xy, 1.0, 1.0);
}
"""

_SKY_FRAGMENT = """
uniform float u_sky_depth;
uniform uint u_sky_tag;
in vec3 v_color;
layout(location = 0) out vec4 f_color;
DEPTH_OUT
layout(location = 2) out uvec4 f_labels;
layout(location = 3) out uint f_tag;
void main() {
    f_color = vec4(clamp(v_color, 0.0, 1.0), 1.0);
    f_depth = depth_out(u_sky_depth);
    f_labels = uvec4(u_sky_tag, 0u, 0u, 255u);
    f_tag = u_sky_tag;
}
"""


# The sun's shadow map: depth only, seen along the sun's rays (an orthographic projection, renderer.sun_view).
SHADOW_VERTEX = """#version 330
uniform mat4 u_sun_viewproj;
in vec3 in_pos;
void main() {
    gl_Position = u_sun_viewproj * vec4(in_pos, 1.0);
}
"""
SHADOW_FRAGMENT = """#version 330
void main() {
}
"""


def sky_vertex(clouds: bool, falloff: bool = False, airlight: bool = False, software: bool = False) -> str:
    """The sky vertex shader, with or without the cloud layer, a fog thinning with height and the low beam's glow
    (``software``: fewer samples of the glow)."""
    header = (f"#version 330\n#define CLOUDS {int(clouds)}\n#define FALLOFF {int(falloff)}\n#define AIRLIGHT {int(airlight)}\n"
              "#define OWN 1\n#define OWN_BLOCKED 1\n"
              f"#define MAX_LIGHTS {MAX_LIGHTS}\n#define AIRLIGHT_SAMPLES {_airlight_samples(software)}\n"
              f"#define AIRLIGHT_REACH {AIRLIGHT_REACH:.1f}\n")  # fmt: skip
    return header + _functions(_SKY_VERTEX)


def sky_fragment(depth8: bool = False, packed: bool = False) -> str:
    """The sky fragment shader (``depth8``: uint8 metres, not float, in the depth target; ``packed``: one output)."""
    return "#version 330\n" + _fragment(_SKY_FRAGMENT, depth8, packed)


# The JPEG's Y, Cb, Cr planes from a colour target, in libjpeg's integer arithmetic (codecs.jpeg.jpeg_planes is the
# reference): the CPU then skips libjpeg's colour conversion, and the read-back shrinks from 4 to 1.5 bytes a pixel.
# A compute shader, not a fragment pass: on an H100 only a few SMs rasterise, and the two fragment passes this
# replaced took 0.44 ms of GPU time per 1600×900 camera against 0.03 ms for this dispatch over all SMs.
#: Work-group size of :data:`PLANES_COMPUTE` (x, y), in 2×2 pixel blocks.
PLANES_GROUP = (16, 8)
PLANES_COMPUTE = """#version 430
layout(local_size_x = GROUP_X, local_size_y = GROUP_Y) in;
uniform sampler2D u_color;
layout(r8ui, binding = 1) writeonly uniform uimage2D u_y;
layout(r8ui, binding = 2) writeonly uniform uimage2D u_cb;
layout(r8ui, binding = 3) writeonly uniform uimage2D u_cr;
void main() {
    // One invocation per 2×2 block: its four Y samples and the block's averaged Cb and Cr.
    ivec2 q = ivec2(gl_GlobalInvocationID.xy);
    ivec2 half_size = imageSize(u_cb);
    if (q.x >= half_size.x || q.y >= half_size.y) return;
    int cb = 0;
    int cr = 0;
    for (int k = 0; k < 4; ++k) {
        ivec2 p = 2 * q + ivec2(k & 1, k >> 1);
        ivec3 c = ivec3(round(texelFetch(u_color, p, 0).rgb * 255.0));
        imageStore(u_y, p, uvec4(uint((19595 * c.r + 38470 * c.g + 7471 * c.b + 32768) >> 16)));
        cb += (-11059 * c.r - 21709 * c.g + 32768 * c.b + 8388608 + 32767) >> 16;
        cr += (32768 * c.r - 27439 * c.g - 5329 * c.b + 8388608 + 32767) >> 16;
    }
    int bias = 1 + (q.x & 1);  // libjpeg's h2v2 downsampling alternates its rounding bias by column
    imageStore(u_cb, q, uvec4(uint((cb + bias) >> 2)));
    imageStore(u_cr, q, uvec4(uint((cr + bias) >> 2)));
}
""".replace("GROUP_X", str(PLANES_GROUP[0])).replace("GROUP_Y", str(PLANES_GROUP[1]))


# A one-byte texture's rows, one after the other, as 32-bit words of a storage buffer: the read-back of the one-byte
# targets (texture_pack.py). With many processes sharing an H100, glReadPixels of a frame's ~67 MB took 4.8 ms of the
# GPU's time (the driver converts through the few graphics units); this pass over all SMs and one buffer copy, 1.3 ms.
#: Work-group size of :data:`BYTES_COMPUTE`, in words.
BYTES_GROUP = 256
BYTES_COMPUTE = """#version 430
layout(local_size_x = GROUP) in;
layout(r8ui, binding = 0) readonly uniform uimage2D u_texture;
layout(std430, binding = 0) writeonly buffer Bytes { uint words[]; };
uniform int u_width;  // texels per row
uniform int u_bytes;  // texels in all
uniform int u_first;  // the word the texture's first byte goes to
void main() {
    int k = int(gl_GlobalInvocationID.x);
    int b = 4 * k;
    if (b >= u_bytes) return;
    ivec2 p = ivec2(b % u_width, b / u_width);
    uint word = 0u;
    // Bytes past the texture's end stay zero: they fall in the padding up to the next aligned read.
    for (int j = 0; j < 4 && b + j < u_bytes; ++j) {
        word |= imageLoad(u_texture, p).r << (8 * j);
        p.x += 1;
        if (p.x == u_width) p = ivec2(0, p.y + 1);
    }
    words[u_first + k] = word;
}
""".replace("GROUP", str(BYTES_GROUP))

#: Work-group size of :data:`UNPACK_COMPUTE` (x, y), in pixels.
UNPACK_GROUP = (16, 8)
# The packed target's pixels spread over the colour, depth, label and tag targets the read-back and the JPEG planes
# use (LABELS 0: colour only, for unlabelled cameras). Colour goes in as k / 255, which an RGBA8 image stores as k.
UNPACK_COMPUTE = """#version 430
layout(local_size_x = GROUP_X, local_size_y = GROUP_Y) in;
layout(rg32ui, binding = 0) readonly uniform uimage2D u_packed;
layout(rgba8, binding = 1) writeonly uniform image2D u_color;
#if LABELS
layout(r8ui, binding = 2) writeonly uniform uimage2D u_depth;
#if ROWS
layout(r8ui, binding = 3) writeonly uniform uimage2D u_labels;
#else
layout(rgba8ui, binding = 3) writeonly uniform uimage2D u_labels;
#endif
layout(r8ui, binding = 4) writeonly uniform uimage2D u_tags;
#endif
void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    ivec2 size = imageSize(u_packed);
    if (p.x >= size.x || p.y >= size.y) return;
    uvec2 v = imageLoad(u_packed, p).xy;
    imageStore(u_color, p, vec4(float(v.x & 255u), float((v.x >> 8) & 255u), float((v.x >> 16) & 255u), 255.0) / 255.0);
#if LABELS
    uint tag = v.x >> 24;
#if ROWS
    // PNG scanlines: filter byte 0 (None) in column 0, then the row; the labels four bytes per pixel.
    if (p.x == 0) {
        imageStore(u_depth, ivec2(0, p.y), uvec4(0u));
        imageStore(u_labels, ivec2(0, p.y), uvec4(0u));
        imageStore(u_tags, ivec2(0, p.y), uvec4(0u));
    }
    int x = 4 * p.x + 1;
    imageStore(u_depth, ivec2(p.x + 1, p.y), uvec4(v.y >> 16));
    imageStore(u_labels, ivec2(x, p.y), uvec4(tag));
    imageStore(u_labels, ivec2(x + 1, p.y), uvec4(v.y & 255u));
    imageStore(u_labels, ivec2(x + 2, p.y), uvec4((v.y >> 8) & 255u));
    imageStore(u_labels, ivec2(x + 3, p.y), uvec4(255u));
    imageStore(u_tags, ivec2(p.x + 1, p.y), uvec4(tag));
#else
    imageStore(u_depth, p, uvec4(v.y >> 16));
    imageStore(u_labels, p, uvec4(tag, v.y & 255u, (v.y >> 8) & 255u, 255u));
    imageStore(u_tags, p, uvec4(tag));
#endif
#endif
}
""".replace("GROUP_X", str(UNPACK_GROUP[0])).replace("GROUP_Y", str(UNPACK_GROUP[1]))


def unpack_compute(labels: bool, png_rows: bool = False) -> str:
    """The unpacking compute shader for labelled cameras (all four targets, as PNG scanlines with ``png_rows``) or
    colour-only ones."""
    defines = f"#version 430\n#define LABELS {int(labels)}\n#define ROWS {int(labels and png_rows)}"
    return UNPACK_COMPUTE.replace("#version 430", defines, 1)
