// Pass 2b: exclusive prefix sums of the slot counts within blocks of SCAN_BLOCK slots (each
// invocation owns 4 consecutive slots), and each block's total for pass 2c.

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> count: array<vec4<u32>>;
@group(0) @binding(2) var<storage, read_write> start: array<vec4<u32>>;
@group(0) @binding(3) var<storage, read_write> partial: array<u32>;

var<workgroup> sums: array<u32, WORKGROUP_SIZE>;

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let block = wid.x + wid.y * nwg.x;
    let live = block < scan_blocks();
    let q = block * WORKGROUP_SIZE + lid;
    var c = vec4<u32>(0u);
    if live {
        c = count[q];
    }
    let total = c.x + c.y + c.z + c.w;
    let before = workgroup_exclusive_scan(lid, total);
    if live {
        start[q] = before + vec4<u32>(0u, c.x, c.x + c.y, c.x + c.y + c.z);
        if lid == WORKGROUP_SIZE - 1u {
            partial[block] = before + total;
        }
    }
}

// The sum of `x` over the invocations before `lid` (Hillis–Steele over the workgroup). Must be
// reached by the whole workgroup.
fn workgroup_exclusive_scan(lid: u32, x: u32) -> u32 {
    sums[lid] = x;
    workgroupBarrier();
    for (var d = 1u; d < WORKGROUP_SIZE; d = d * 2u) {
        var y = 0u;
        if lid >= d {
            y = sums[lid - d];
        }
        workgroupBarrier();
        sums[lid] += y;
        workgroupBarrier();
    }
    return sums[lid] - x;
}
