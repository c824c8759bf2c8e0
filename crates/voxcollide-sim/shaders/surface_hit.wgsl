// One probe's result of the surface contact's search on the device, which the search
// (surface_search.wgsl), the passes after it (surface_forces.wgsl) and the gather
// (surface_gather.wgsl) share. Keep in sync with `GpuHit` in src/gpu/surface.rs.

struct SurfaceHit {
    normal: vec4<f32>,  // xyz: the push's direction, out of the partner; w: its depth, gap - s
    weights: vec4<f32>, // xyz: the nearest point's barycentric weights; w: s, the signed distance
    entry: vec4<f32>,   // in: xyz the way the probe was pushed out at the last step (0: none)
    triangle: u32,      // the nearest triangle within the cutoff (NONE: none)
    found: u32,         // 1: pushed, or listed within the margin; 0: not
    clear: f32,         // how far the probe and the partner may still move before it could be
                        // pushed (above 0: not searched; `Side::clear` on the CPU)
    _pad1: u32,
}
