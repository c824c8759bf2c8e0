// `voxcollide view` (src/view/blit.rs): puts a frame on the window. The renderer's picture,
// drawn on the device and never read back, with the overlay composed over it: the legend and
// the heads-up lines, drawn on the CPU as premultiplied sRGB bytes. They are composed as the
// CPU composes a legend over a picture, in sRGB-encoded values, pixel for pixel (both are the
// window's size, so nothing is sampled or filtered), by one triangle that covers the screen.

// Whether the target encodes linear light as sRGB (a window's `…Srgb` surface): then the
// composed value is decoded for it. A linear target (a screenshot's) takes it as it is.
override SRGB_TARGET: bool = true;

// The renderer's picture: an sRGB texture, its texels read as linear light.
@group(0) @binding(0) var picture: texture_2d<f32>;
// The overlay: sRGB-encoded colour premultiplied by its alpha (0 where nothing is drawn).
@group(0) @binding(1) var overlay: texture_2d<f32>;

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

fn encode(c: vec3<f32>) -> vec3<f32> {
    return select(1.055 * pow(c, vec3<f32>(1.0 / 2.4)) - 0.055, 12.92 * c, c <= vec3<f32>(0.0031308));
}

fn decode(s: vec3<f32>) -> vec3<f32> {
    return select(pow((s + 0.055) / 1.055, vec3<f32>(2.4)), s / 12.92, s <= vec3<f32>(0.04045));
}

@fragment
fn fs_main(v: VertexOut) -> @location(0) vec4<f32> {
    let xy = vec2<i32>(v.position.xy);
    let under = encode(clamp(textureLoad(picture, xy, 0).rgb, vec3<f32>(0.0), vec3<f32>(1.0)));
    let over = textureLoad(overlay, xy, 0);
    let composed = over.rgb + under * (1.0 - over.a);
    if SRGB_TARGET {
        return vec4<f32>(decode(composed), 1.0);
    }
    return vec4<f32>(composed, 1.0);
}
