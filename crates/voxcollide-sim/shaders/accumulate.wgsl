// Simulation pass 0: a body's contact forces from several contacts, summed in contact order
// (the first one copied, the others added), as the CPU sums them (CpuWorld::step).

struct AccumulateParams {
    n: u32,
    first: u32,
    _pad0: u32,
    _pad1: u32,
}

@group(0) @binding(0) var<uniform> acc_params: AccumulateParams;
@group(0) @binding(1) var<storage, read> src: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> dst: array<vec4<f32>>;

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let i = gid.x + gid.y * nwg.x * WORKGROUP_SIZE;
    if i >= acc_params.n {
        return;
    }
    let f = src[i].xyz;
    if acc_params.first != 0u {
        dst[i] = vec4<f32>(f, 0.0);
    } else {
        dst[i] = vec4<f32>(dst[i].xyz + f, 0.0);
    }
}
