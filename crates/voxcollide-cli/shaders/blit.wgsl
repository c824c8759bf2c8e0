// `voxcollide view` (src/view.rs): copies the finished picture (the renderer's, with its legend
// and heads-up line drawn on it) onto the window, pixel for pixel, with one triangle that covers
// the screen. The picture is the window's size, so no sampling or filtering is involved.

@group(0) @binding(0) var picture: texture_2d<f32>;

struct VertexOut {
    @builtin(position) position: vec4<f32>,
}

@vertex
fn vs_main(@builtin(vertex_index) i: u32) -> VertexOut {
    // (-1, 1), (3, 1), (-1, -3): a triangle whose inside covers the whole clip square.
    let uv = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u));
    var out: VertexOut;
    out.position = vec4<f32>(uv.x * 2.0 - 1.0, 1.0 - uv.y * 2.0, 0.0, 1.0);
    return out;
}

@fragment
fn fs_main(v: VertexOut) -> @location(0) vec4<f32> {
    return textureLoad(picture, vec2<i32>(v.position.xy), 0);
}
