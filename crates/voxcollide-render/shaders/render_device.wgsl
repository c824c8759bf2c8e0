// The device path's vertex stage (src/device.rs), composed after render.wgsl, whose fragment
// stage it shares: each corner of each triangle is read from buffers that live on the device
// (the positions a simulation keeps there), so a frame is drawn without reading them back.
// The triangle's face normal is taken from its three corners (flat shading, as the host path
// does), and the colour-map coordinate from how far the corner has moved from its start.

// Keep in sync with `GpuMeshParams` in src/device.rs.
struct MeshParams {
    // rgb: the mesh's base colour, linear.
    color: vec4<f32>,
    // x: the scalar range's low end; y: 1 / (hi − lo) (0 when lo == hi); z: 1 to colour by
    // the distance moved, 0 for the base colour.
    scalar: vec4<f32>,
}

@group(1) @binding(0) var<uniform> mesh: MeshParams;
// One vec4 per vertex, xyz its position (w unused): a simulation's own buffer.
@group(1) @binding(1) var<storage, read> positions: array<vec4<f32>>;
// Where each vertex started, xyz.
@group(1) @binding(2) var<storage, read> start: array<vec4<f32>>;
// Three vertex indices per triangle, counter-clockwise seen from outside.
@group(1) @binding(3) var<storage, read> corners: array<u32>;

fn finite3(p: vec3<f32>) -> bool {
    let bits = bitcast<vec3<u32>>(p) & vec3<u32>(0x7f800000u);
    return all(bits != vec3<u32>(0x7f800000u));
}

@vertex
fn vs_device(@builtin(vertex_index) index: u32) -> VertexOut {
    let t = index / 3u;
    let a = positions[corners[3u * t]].xyz;
    let b = positions[corners[3u * t + 1u]].xyz;
    let c = positions[corners[3u * t + 2u]].xyz;
    let v = corners[index];
    let here = positions[v].xyz;
    let n = cross(b - a, c - a);
    let area = length(n);
    var out: VertexOut;
    // A triangle with a broken corner (a blown-up simulation) or no area is not drawn: all
    // three corners, deciding alike, go outside the clip volume.
    if !(finite3(a) && finite3(b) && finite3(c)) || !(area > 0.0) || !finite3(n / area) {
        out.clip_position = vec4<f32>(2.0, 2.0, 2.0, 1.0);
        out.world = vec3<f32>(0.0);
        out.normal_t = vec4<f32>(0.0, 0.0, 1.0, -1.0);
        out.color = mesh.color.rgb;
        return out;
    }
    var s = -1.0;
    if mesh.scalar.z > 0.5 {
        let moved = length(here - start[v].xyz);
        s = select(-1.0, clamp((moved - mesh.scalar.x) * mesh.scalar.y, 0.0, 1.0), moved == moved);
    }
    out.clip_position = params.view_proj * vec4<f32>(here, 1.0);
    out.world = here;
    out.normal_t = vec4<f32>(n / area, s);
    out.color = mesh.color.rgb;
    return out;
}
