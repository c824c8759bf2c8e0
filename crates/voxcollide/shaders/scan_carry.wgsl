// Pass 2c (one workgroup): exclusive prefix sums of the block totals, in place, SCAN_BLOCK
// totals per round with the running carry.

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> partial: array<vec4<u32>>;
@group(0) @binding(2) var<storage, read> changed: array<u32>;

var<workgroup> resort: u32;

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(@builtin(local_invocation_index) lid: u32) {
    // Kept order (bin.wgsl): nothing to scan.
    if lid == 0u {
        resort = changed[0];
    }
    if workgroupUniformLoad(&resort) == 0u {
        return;
    }
    let quads = (scan_blocks() + 3u) / 4u;
    let rounds = (quads + WORKGROUP_SIZE - 1u) / WORKGROUP_SIZE;
    var carry = 0u;
    for (var r = 0u; r < rounds; r++) {
        let q = r * WORKGROUP_SIZE + lid;
        var c = vec4<u32>(0u);
        if q < quads {
            c = partial[q];
        }
        let total = c.x + c.y + c.z + c.w;
        let before = carry + workgroup_exclusive_scan(lid, total);
        if q < quads {
            partial[q] = before + vec4<u32>(0u, c.x, c.x + c.y, c.x + c.y + c.z);
        }
        carry += sums[WORKGROUP_SIZE - 1u];
        workgroupBarrier();
    }
}
