// Pass 2b: exclusive prefix sums of the slot counts within blocks of SCAN_BLOCK slots (each
// invocation owns SCAN_PER_INVOCATION consecutive slots, read as vec4s), and each block's total
// for pass 2c.

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> count: array<vec4<u32>>;
@group(0) @binding(2) var<storage, read_write> start: array<vec4<u32>>;
@group(0) @binding(3) var<storage, read_write> partial: array<u32>;
@group(0) @binding(4) var<storage, read> changed: array<u32>;

var<workgroup> resort: u32;

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    // A body whose slots are all as they were keeps its order (bin.wgsl): nothing to scan.
    if lid == 0u {
        resort = changed[0];
    }
    if workgroupUniformLoad(&resort) == 0u {
        return;
    }
    let block = wid.x + wid.y * nwg.x;
    let live = block < scan_blocks();
    let quads = SCAN_PER_INVOCATION / 4u;
    let q = (block * WORKGROUP_SIZE + lid) * quads;
    var c: array<vec4<u32>, SCAN_PER_INVOCATION / 4u>;
    var total = 0u;
    if live {
        for (var k = 0u; k < quads; k++) {
            c[k] = count[q + k];
            total += c[k].x + c[k].y + c[k].z + c[k].w;
        }
    }
    let before = workgroup_exclusive_scan(lid, total);
    if live {
        var sum = before;
        for (var k = 0u; k < quads; k++) {
            let x = c[k];
            start[q + k] = sum + vec4<u32>(0u, x.x, x.x + x.y, x.x + x.y + x.z);
            sum += x.x + x.y + x.z + x.w;
        }
        if lid == WORKGROUP_SIZE - 1u {
            partial[block] = sum;
        }
    }
}
