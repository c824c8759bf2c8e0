// Pass 1b (one invocation): this step's grid center and origin. FollowA: 0.5 * (lo + hi) of A's
// finite vertices, or the built center when A has none; Fixed: the built center.

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> state: State;

fn from_key(key: u32) -> f32 {
    return bitcast<f32>(select(~key, key & 0x7fffffffu, (key & 0x80000000u) != 0u));
}

@compute @workgroup_size(1)
fn main() {
    var center = params.center.xyz;
    if params.anchor == ANCHOR_FOLLOW_A && atomicLoad(&state.max_key[0]) != 0u {
        var lo: vec3<f32>;
        var hi: vec3<f32>;
        for (var k = 0u; k < 3u; k++) {
            lo[k] = from_key(~atomicLoad(&state.min_key[k]));
            hi[k] = from_key(atomicLoad(&state.max_key[k]));
        }
        center = 0.5 * (lo + hi);
        if !is_finite3(center) {
            atomicOr(&state.status, STATUS_NON_FINITE_CENTER);
        }
    }
    state.center = vec4<f32>(center, 0.0);
    state.origin = vec4<f32>(center - params.half_extent.xyz, 0.0);
}
