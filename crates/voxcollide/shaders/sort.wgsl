// Pass 2e: every binned vertex to the next free place of its slot, with its index in w. For A
// (BODY 0), so that the vertices of consecutive slots (a block row's voxels) are one contiguous
// range for the probe; for B (BODY 1), so that the probe's neighbouring invocations walk
// neighbouring slots whatever order B comes in. The order within a slot varies from run to
// run; no result depends on it (candidates are ranked by (d2, index), forces are summed
// exactly, and each B vertex's force goes to its own index).

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> state: State;
@group(0) @binding(2) var<storage, read> pos: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read_write> cursor: array<atomic<u32>>;
@group(0) @binding(4) var<storage, read_write> sorted: array<vec4<u32>>; // (position bits, index)
@group(0) @binding(5) var<storage, read> changed: array<u32>;

// 0: body A (params.n_a vertices); 1: body B (params.n_b).
override BODY: u32 = 0u;

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let i = item_index(gid, nwg);
    // Kept order (bin.wgsl): gather.wgsl brings the positions instead.
    if i >= select(params.n_a, params.n_b, BODY == 1u) || changed[0] == 0u {
        return;
    }
    let p = pos[i].xyz;
    let v = voxel_of(p, state.origin.xyz);
    if v.w == 1u {
        sorted[atomicAdd(&cursor[slot_of(v.xyz)], 1u)] = vec4<u32>(bitcast<vec3<u32>>(p), i);
    }
}
