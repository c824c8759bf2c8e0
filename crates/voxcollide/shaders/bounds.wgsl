// Pass 1 (FollowA only): the per-axis min and max of A's finite vertices, as order-preserving
// integer keys, reduced per workgroup and then with one atomic per workgroup and axis.

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> state: State;
@group(0) @binding(2) var<storage, read> pos_a: array<vec4<f32>>;

var<workgroup> wg_min: array<atomic<u32>, 3>;
var<workgroup> wg_max: array<atomic<u32>, 3>;

// A u32 that orders like the float: flip every bit of a negative, the sign bit of a positive.
// Never 0 for a finite float, so 0 can mean "no value".
fn order_key(x: f32) -> u32 {
    let bits = bitcast<u32>(x);
    return select(bits | 0x80000000u, ~bits, (bits & 0x80000000u) != 0u);
}

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let i = item_index(gid, nwg);
    if i < params.n_a {
        let p = pos_a[i].xyz;
        if is_finite3(p) {
            for (var k = 0u; k < 3u; k++) {
                let key = order_key(p[k]);
                atomicMax(&wg_min[k], ~key);
                atomicMax(&wg_max[k], key);
            }
        }
    }
    workgroupBarrier();
    if lid < 3u {
        let lo = atomicLoad(&wg_min[lid]);
        if lo != 0u {
            atomicMax(&state.min_key[lid], lo);
            atomicMax(&state.max_key[lid], atomicLoad(&wg_max[lid]));
        }
    }
}
