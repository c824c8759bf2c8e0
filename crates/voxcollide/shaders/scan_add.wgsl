// Pass 2d: each slot's start = its offset within its block + the block's offset, so that the
// vertices of slot s will sit at start[s] .. start[s + 1] of the sorted array; `cursor` starts
// as a copy for pass 2e to count up.

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> start: array<vec4<u32>>;
@group(0) @binding(2) var<storage, read> partial: array<u32>;
@group(0) @binding(3) var<storage, read_write> cursor: array<vec4<u32>>;
@group(0) @binding(4) var<storage, read> changed: array<u32>;

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let q = item_index(gid, nwg);
    // Kept order (bin.wgsl): the starts stand.
    if q < scan_blocks() * (SCAN_BLOCK / 4u) && changed[0] != 0u {
        let s = start[q] + vec4<u32>(partial[q / (SCAN_BLOCK / 4u)]);
        start[q] = s;
        cursor[q] = s;
    }
}
