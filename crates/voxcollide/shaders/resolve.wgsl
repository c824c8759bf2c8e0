// Pass 4: A's fixed-point totals back to f32 forces, f32(count) * unit, from slot order to A's
// own (A's vertices outside the grid keep the cleared zero). A total outside i32 leaves 0 and
// records the first such (vertex, axis) for Error::ForceOverflow.

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> state: State;
// Per sorted A vertex: the low words of the x, y, z totals (w unused), then the high words.
@group(0) @binding(2) var<storage, read> fixed: array<vec4<u32>>;
// A in slot order: (position bits, index in A).
@group(0) @binding(3) var<storage, read> sorted: array<vec4<u32>>;
@group(0) @binding(4) var<storage, read_write> force_a: array<vec4<f32>>;

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let at = item_index(gid, nwg);
    if at >= atomicLoad(&state.binned) {
        return;
    }
    let i = sorted[at].w;
    var f = vec3<f32>(0.0);
    let low = fixed[2u * at].xyz;
    let high = fixed[2u * at + 1u].xyz;
    for (var k = 0u; k < 3u; k++) {
        // The total T = high * 2^32 + (low ^ 2^31) - 2^31 (see add_fixed in probe.wgsl) fits
        // i32 iff the high word is 0; T is then the low word as i32.
        if high[k] == 0u {
            f[k] = f32(bitcast<i32>(low[k])) * params.unit;
        } else {
            atomicMax(&state.overflow, ~(3u * i + k));
        }
    }
    force_a[i] = vec4<f32>(f, 0.0);
}
