// Pass 2a: count the vertices of every slot (a counting sort by slot, docs/design.md §3's VoxelData):
// each vertex whose voxel is inside the grid adds one to its slot's count. Run for A (BODY 0),
// and for B (BODY 1) by A's slots, so that the probe walks B in A's slot order whatever order B
// comes in. CPU twins: VoxelData::bin, and parallel/sort.rs.
//
// Each vertex's slot is kept (`keys`, the slot + 1, or 0xFFFFFFFF outside the grid): where one
// differs from the last step's, `changed` is set and the body is sorted again; where none does,
// its last order stands, and `gather.wgsl` only brings its positions up to date (the passes
// that sort it return at once). The host clears `keys` to 0 when the sizes or the table
// change, which no slot is.

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> state: State;
@group(0) @binding(2) var<storage, read> pos: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read_write> count: array<atomic<u32>>;
@group(0) @binding(4) var<storage, read_write> keys: array<u32>;
@group(0) @binding(5) var<storage, read_write> changed: array<atomic<u32>>;

// 0: body A (params.n_a vertices, counted in state.binned); 1: body B (state.binned_b).
override BODY: u32 = 0u;

var<workgroup> wg_binned: atomic<u32>;

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let i = item_index(gid, nwg);
    if i < select(params.n_a, params.n_b, BODY == 1u) {
        let v = voxel_of(pos[i].xyz, state.origin.xyz);
        var key = 0xFFFFFFFFu;
        if v.w == 1u {
            let s = slot_of(v.xyz);
            atomicAdd(&count[s], 1u);
            atomicAdd(&wg_binned, 1u);
            key = s + 1u;
        }
        if keys[i] != key {
            keys[i] = key;
            atomicStore(&changed[0], 1u);
        }
    }
    workgroupBarrier();
    if lid == 0u {
        let n = atomicLoad(&wg_binned);
        if n != 0u {
            if BODY == 0u {
                atomicAdd(&state.binned, n);
            } else {
                atomicAdd(&state.binned_b, n);
            }
        }
    }
}
