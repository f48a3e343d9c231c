"""GLSL sources of the camera renderer (kept as Python strings so they ship inside the package).

The scene program draws into four colour attachments at once: 0 = RGBA8 colour, 1 = R32F planar depth (metres
along the optical axis; R8UI uint8 metres, rounded as the depth PNG stores them, when ``DEPTH8``), 2 = R8UI semantic
tag and instance id packed as RGBA8UI (tag, id low byte, id high byte, 255: the bytes of an instance PNG pixel, so
the read-back is the image the PNG encoder takes). It is compiled once per material and weather
variant (``#define`` switches) because a software rasteriser runs every branch of a shader for every pixel:
specialised programs keep each pixel's work to what its material needs. The sky program fills the pixels no
geometry covered with the sky colour, a depth of :data:`SKY_DEPTH` and the sky tag.

For the same reason lighting, fog and reflections are computed per vertex (meshes are tessellated finely enough
for that: 2 m road strips, an 8 m terrain grid, a sky grid) and fragment shaders mostly copy an interpolated colour.
"""

from __future__ import annotations

#: Depth written for sky pixels: CARLA's far plane (1000 m).
SKY_DEPTH = 1000.0
#: CARLA semantic tag of sky pixels.
SKY_TAG = 11

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
uniform vec3 u_fog_color;
uniform float u_fog_density;
uniform float u_fog_start;
uniform float u_wetness;
uniform float u_night;
#if NIGHT
uniform sampler2D u_lightmap;
uniform vec4 u_lightmap_rect;
uniform vec3 u_head_pos;
uniform vec3 u_head_dir;
#endif
in vec3 in_pos;
in vec3 in_normal;
in vec4 in_color;
in uvec2 in_ids;
out vec3 v_color;
out float v_depth;
flat out uvec2 v_ids;
#if MAT == 2
out vec3 v_alt;
out vec2 v_facade;
flat out float v_wall;
#if NIGHT
out vec3 v_alt_lit;
#endif
#elif MAT == 1 && WET
out vec3 v_alt;
out vec2 v_xy;
#endif

vec3 glossy(vec3 col, vec3 n, vec3 v, float gloss, float mirror) {
    // Fresnel-weighted reflection of the sky (dimmed by ``mirror``: streets reflect buildings, not only sky)
    // plus a sun highlight.
    vec3 r = reflect(-v, n);
    float fres = 0.04 + 0.96 * pow(1.0 - max(dot(n, v), 0.0), 5.0);
    vec3 sky = mix(u_sky_horizon, u_sky_zenith, sqrt(clamp(r.z, 0.0, 1.0))) * mirror;
    vec3 hv = normalize(u_sun_dir + v);
    return mix(col, sky, fres * gloss) + u_sun_color * pow(max(dot(n, hv), 0.0), 60.0) * gloss * 1.5;
}

void main() {
    vec3 p = in_pos;
    vec3 to_cam = u_cam_pos - p;
    float dist = length(to_cam);
    vec3 v = to_cam / max(dist, 1e-4);
    vec3 n = normalize(in_normal);
    n = dot(n, v) < 0.0 ? -n : n;
    vec3 albedo = in_color.rgb;
    vec3 light = mix(u_ambient_ground, u_ambient_sky, n.z * 0.5 + 0.5) + u_sun_color * max(dot(n, u_sun_dir), 0.0);
#if NIGHT
    vec2 luv = (p.xy - u_lightmap_rect.xy) * u_lightmap_rect.zw;
    float lamp = textureLod(u_lightmap, luv, 0.0).r * clamp(1.0 - (p.z - 0.5) / 6.0, 0.0, 1.0);
    vec3 hl = p - u_head_pos;
    float hd = length(hl);
    vec3 hdir = hl / max(hd, 1e-3);
    float cone = smoothstep(0.8, 0.95, dot(hdir, u_head_dir));
    float facing = max(dot(n, -hdir), 0.0) * 0.8 + 0.2;
    float reach = hd / 12.0;
    vec3 lamps = vec3(1.0, 0.82, 0.58) * lamp * 0.35;
    vec3 beam = vec3(1.0, 0.96, 0.85) * cone * facing * 0.75 / (1.0 + reach * reach);
    light += (lamps + beam) * u_night;
#endif
    float fog = 1.0 - exp(-u_fog_density * max(dist - u_fog_start, 0.0));
    vec3 col = albedo * light;
#if MAT == 4
    col += albedo * (0.25 + 1.6 * u_night);
#elif MAT == 3
    col = glossy(col, n, v, 0.7, 1.0);
#elif MAT == 6
    col = glossy(col, n, v, 0.12, 1.0);
#elif MAT == 1 && WET
    vec3 wet = glossy(albedo * 0.45 * light, n, v, 0.6, 0.45);
    col = mix(col, wet, u_wetness);
    v_alt = mix(wet, u_fog_color, fog);
    v_xy = p.xy * 0.029;
#elif MAT == 2
    vec3 window = glossy(vec3(0.11, 0.14, 0.18) * light, n, v, 0.45, 1.0);
    v_alt = mix(window, u_fog_color, fog);
#if NIGHT
    v_alt_lit = mix(window + vec3(1.0, 0.78, 0.45) * 0.32 * u_night, u_fog_color, fog);
#endif
    float side = abs(n.x) > abs(n.y) ? p.y : p.x;
    v_facade = vec2(side / 3.1, p.z / 3.3);
    v_wall = abs(n.z) < 0.5 ? 1.0 : 0.0;
#endif
    v_color = mix(col, u_fog_color, fog);
    v_depth = dot(p - u_cam_pos, u_cam_fwd);
    v_ids = in_ids;
    gl_Position = u_viewproj * vec4(p, 1.0);
}
"""

_SCENE_FRAGMENT = """
uniform float u_puddles;
uniform sampler2D u_noise;
in vec3 v_color;
in float v_depth;
flat in uvec2 v_ids;
#if MAT == 2
in vec3 v_alt;
in vec2 v_facade;
flat in float v_wall;
#if NIGHT
in vec3 v_alt_lit;
#endif
#elif MAT == 1 && WET
in vec3 v_alt;
in vec2 v_xy;
#endif
layout(location = 0) out vec4 f_color;
DEPTH_OUT
layout(location = 2) out uvec4 f_labels;
layout(location = 3) out uint f_tag;

void main() {
    // Lighting, fog and reflections come per vertex; here only per-pixel patterns pick between two colours.
    vec3 col = v_color;
#if MAT == 2
    vec2 f = fract(v_facade);
    float win = v_wall * step(1.0, v_facade.y) * step(0.22, f.x) * step(f.x, 0.78) * step(0.3, f.y) * step(f.y, 0.82);
#if NIGHT
    vec2 cell = floor(v_facade);
    float lit = step(0.72, fract(sin(dot(cell, vec2(12.9898, 78.233))) * 43758.5453));
    col = mix(col, mix(v_alt, v_alt_lit, lit), win);
#else
    col = mix(col, v_alt, win);
#endif
#elif MAT == 1 && WET
    float blob = texture(u_noise, v_xy).g;
    col = mix(col, v_alt, smoothstep(0.66, 0.72, blob + 0.25 * u_puddles) * u_puddles);
#endif
    f_color = vec4(clamp(col, 0.0, 1.0), 1.0);
    f_depth = depth_out(v_depth);
    f_labels = uvec4(v_ids.x, v_ids.y & 255u, (v_ids.y >> 8) & 255u, 255u);
    f_tag = v_ids.x;
}
"""


def scene_vertex(material: int, night: bool, wet: bool) -> str:
    """The scene vertex shader specialised for one material and weather variant."""
    return _header(material, night, wet) + _SCENE_VERTEX


def _header(material: int, night: bool, wet: bool) -> str:
    return f"#version 330\n#define MAT {int(material)}\n#define NIGHT {int(night)}\n#define WET {int(wet)}\n"


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


def scene_fragment(material: int, night: bool, wet: bool, depth8: bool = False, packed: bool = False) -> str:
    """The scene fragment shader for one material and weather variant (``depth8``: uint8 metres, not float;
    ``packed``: one RG32UI output, see :data:`UNPACK_COMPUTE`)."""
    return _header(material, night, wet) + _fragment(_SCENE_FRAGMENT, depth8, packed)


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
uniform float u_fog_density;
uniform sampler2D u_noise;
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
    vec3 cloud = mix(u_sky_horizon, vec3(1.0), 0.55) * (0.5 + 0.5 * (1.0 - u_cloudiness)) * (0.8 + 0.3 * nz);
    col = mix(col, cloud, cover * smoothstep(0.0, 0.1, e));
#endif
    float haze = 1.0 - exp(-u_fog_density * 400.0 / (abs(e) * 6.0 + 1.0));
    v_color = mix(col, u_fog_color, haze);
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


def sky_vertex(clouds: bool) -> str:
    """The sky vertex shader, with or without the cloud layer."""
    return f"#version 330\n#define CLOUDS {int(clouds)}\n" + _SKY_VERTEX


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
layout(rgba8ui, binding = 3) writeonly uniform uimage2D u_labels;
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
    imageStore(u_depth, p, uvec4(v.y >> 16));
    imageStore(u_labels, p, uvec4(tag, v.y & 255u, (v.y >> 8) & 255u, 255u));
    imageStore(u_tags, p, uvec4(tag));
#endif
}
""".replace("GROUP_X", str(UNPACK_GROUP[0])).replace("GROUP_Y", str(UNPACK_GROUP[1]))


def unpack_compute(labels: bool) -> str:
    """The unpacking compute shader for labelled cameras (all four targets) or colour-only ones."""
    return UNPACK_COMPUTE.replace("#version 430", f"#version 430\n#define LABELS {int(labels)}", 1)
