// The offscreen renderer's one pipeline (src/render.rs): flat-shaded, two-sided triangles with a
// headlight, a viridis colour map of a per-vertex scalar, and a clip plane that cuts bodies open.

// Keep in sync with `GpuRenderParams` in src/render.rs.
struct Params {
    // World to clip space (depth 0..1, as wgpu expects).
    view_proj: mat4x4<f32>,
    // Unit vector from the surface towards the light (a headlight: near the camera's direction).
    light_dir: vec4<f32>,
    // Plane (n, d): a fragment at p is kept where dot(n, p) + d >= 0; all zero when no clip.
    clip_plane: vec4<f32>,
}

@group(0) @binding(0) var<uniform> params: Params;

// Keep in sync with `GpuVertex` in src/render.rs.
struct VertexIn {
    @location(0) position: vec4<f32>,
    // xyz: the triangle's face normal (flat shading: the same at its three corners);
    // w: colour-map coordinate in [0, 1], or negative for "use the base colour".
    @location(1) normal_t: vec4<f32>,
    // rgb: the mesh's base colour, linear.
    @location(2) color: vec4<f32>,
}

struct VertexOut {
    @builtin(position) clip_position: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) normal_t: vec4<f32>,
    @location(2) color: vec3<f32>,
}

@vertex
fn vs_main(v: VertexIn) -> VertexOut {
    var out: VertexOut;
    out.clip_position = params.view_proj * vec4<f32>(v.position.xyz, 1.0);
    out.world = v.position.xyz;
    out.normal_t = v.normal_t;
    out.color = v.color.rgb;
    return out;
}

// sRGB-encoded to linear, exactly (the colour map's coefficients are sRGB values, the target
// format encodes linear output).
fn srgb_to_linear(c: vec3<f32>) -> vec3<f32> {
    let lo = c / 12.92;
    let hi = pow((c + 0.055) / 1.055, vec3<f32>(2.4));
    return select(hi, lo, c <= vec3<f32>(0.04045));
}

// Viridis (perceptually uniform, readable in grey and by colour-blind viewers), as the degree-6
// polynomial fit by Matt Zucker (shadertoy WlfXRN); returns sRGB-encoded values.
fn viridis(t: f32) -> vec3<f32> {
    let c0 = vec3<f32>(0.2777273272234177, 0.005407344544966578, 0.3340998053353061);
    let c1 = vec3<f32>(0.1050930431085774, 1.404613529898575, 1.384590162594685);
    let c2 = vec3<f32>(-0.3308618287255563, 0.214847559468213, 0.09509516302823659);
    let c3 = vec3<f32>(-4.634230498983486, -5.799100973351585, -19.33244095627987);
    let c4 = vec3<f32>(6.228269936347081, 14.17993336680509, 56.69055260068105);
    let c5 = vec3<f32>(4.776384997670288, -13.74514537774601, -65.35303263337234);
    let c6 = vec3<f32>(-5.435455855934631, 4.645852612178535, 26.3124352495832);
    return c0 + t * (c1 + t * (c2 + t * (c3 + t * (c4 + t * (c5 + t * c6)))));
}

@fragment
fn fs_main(f: VertexOut, @builtin(front_facing) front: bool) -> @location(0) vec4<f32> {
    // The cut-away: the negative side of the clip plane is not drawn, so the inside shows.
    if dot(params.clip_plane.xyz, f.world) + params.clip_plane.w < 0.0 {
        discard;
    }
    var albedo = f.color;
    if f.normal_t.w > -0.5 {
        albedo = srgb_to_linear(clamp(viridis(clamp(f.normal_t.w, 0.0, 1.0)), vec3<f32>(0.0), vec3<f32>(1.0)));
    }
    // Turn the face normal towards the viewer; which side we see is `front` (the mesh's
    // triangles are counter-clockwise seen from outside).
    let n = select(-f.normal_t.xyz, f.normal_t.xyz, front);
    let lambert = max(dot(n, params.light_dir.xyz), 0.0);
    var shade: vec3<f32>;
    if front {
        shade = albedo * (0.25 + 0.75 * lambert);
    } else {
        // Inside surfaces, seen through a cut: darker and greyed, so they read as inside. The
        // grey lifts the map's near-black low end a little, so even there the inside keeps its
        // shape and differs from the saturated outside.
        shade = mix(albedo, vec3<f32>(0.35), 0.3) * (0.1 + 0.3 * lambert);
    }
    return vec4<f32>(shade, 1.0);
}
