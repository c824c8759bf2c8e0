// Shared by the two prefix-sum passes (scan, scan_carry): a workgroup-wide exclusive scan.

var<workgroup> sums: array<u32, WORKGROUP_SIZE>;

// The sum of `x` over the invocations before `lid` (Hillis–Steele over the workgroup); after it,
// sums[WORKGROUP_SIZE - 1] is the workgroup's total. Must be reached by the whole workgroup.
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
