// Pass 2f: a body that kept its order (every vertex in the slot it was sorted into at the last
// step, bin.wgsl) has its new positions brought into that order: each sorted place reads its
// vertex's position. The order is one the sort could have made from these slots, so the probe
// finds what it would after a new sort. CPU twin: SortedBody::sort_keeping in parallel/sort.rs.

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> state: State;
@group(0) @binding(2) var<storage, read> pos: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read_write> sorted: array<vec4<u32>>; // (position bits, index)
@group(0) @binding(4) var<storage, read> changed: array<u32>;

// 0: body A (state.binned places); 1: body B (state.binned_b).
override BODY: u32 = 0u;

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let k = item_index(gid, nwg);
    let binned = select(atomicLoad(&state.binned), atomicLoad(&state.binned_b), BODY == 1u);
    if k >= binned || changed[0] != 0u {
        return;
    }
    let i = sorted[k].w;
    sorted[k] = vec4<u32>(bitcast<vec3<u32>>(pos[i].xyz), i);
}
