// Pass 2a: count the A vertices of every slot (a counting sort by slot, DESIGN §3's
// VoxelData): each A vertex whose voxel is inside the grid adds one to its slot's count. CPU
// twin: VoxelData::bin.

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> state: State;
@group(0) @binding(2) var<storage, read> pos_a: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read_write> count: array<atomic<u32>>;

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
            atomicAdd(&count[slot_of(v.xyz)], 1u);
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
