// A point of the surface a lattice carries (src/gpu/surface.rs, `GpuCarried`; the CPU's
// `Embedding`): where it rests, and its cell's up to 8 kept corners (0xffffffff: none) and their
// trilinear weights. Shared by surface_embed.wgsl and couple_build.wgsl.
struct Carried {
    rest: vec4<f32>,
    corners0: vec4<u32>,
    corners1: vec4<u32>,
    weights0: vec4<f32>,
    weights1: vec4<f32>,
}

// Corner j of 8 of a carried point: (vertex, weight's bits).
fn corner_of(c: Carried, j: u32) -> vec2<u32> {
    if j < 4u {
        return vec2<u32>(c.corners0[j], bitcast<u32>(c.weights0[j]));
    }
    return vec2<u32>(c.corners1[j - 4u], bitcast<u32>(c.weights1[j - 4u]));
}
