// Pass 2: push every A vertex whose voxel is inside the grid onto its voxel's list in the sparse
// voxel hash: next[i] = atomicExchange(&head[slot], i + 1), stored with the vertex's voxel so
// that a walk can tell aliased voxels apart without reading positions. CPU twin: VoxelData::bin.

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> state: State;
@group(0) @binding(2) var<storage, read> pos_a: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read_write> head: array<atomic<u32>>;
@group(0) @binding(4) var<storage, read_write> next: array<vec4<u32>>; // (next entry, voxel xyz)

var<workgroup> wg_binned: atomic<u32>;

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let i = item_index(gid, nwg);
    if i < params.n_a {
        let v = voxel_of(pos_a[i].xyz, state.origin.xyz);
        if v.w == 1u {
            let slot = voxel_hash(v.xyz) & params.slot_mask;
            next[i] = vec4<u32>(atomicExchange(&head[slot], i + 1u), v.xyz);
            atomicAdd(&wg_binned, 1u);
        }
    }
    workgroupBarrier();
    if lid == 0u {
        let n = atomicLoad(&wg_binned);
        if n != 0u {
            atomicAdd(&state.binned, n);
        }
    }
}
