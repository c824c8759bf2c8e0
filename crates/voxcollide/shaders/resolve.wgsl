// Pass 4: A's fixed-point totals back to f32 forces, f32(count) * unit. A total outside i32
// leaves 0 and records the first such (vertex, axis) for Error::ForceOverflow.

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> state: State;
// Per A vertex: the low words of the x, y, z totals (w unused), then the high words.
@group(0) @binding(2) var<storage, read> fixed: array<vec4<u32>>;
@group(0) @binding(3) var<storage, read_write> force_a: array<vec4<f32>>;

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let i = item_index(gid, nwg);
    if i >= params.n_a {
        return;
    }
    var f = vec3<f32>(0.0);
    let low = fixed[2u * i].xyz;
    let high = fixed[2u * i + 1u].xyz;
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
