// The implicit integrator's contact stiffness: each vertex a voxel-model penalty pushes gets
// `k·nnᵀ` along the force it gets (`n` its direction), added over the body's contacts in
// contact order (CPU twin: CpuWorld's `contact_k`). Stored symmetric in two slots of the
// implicit passes' `work` buffer: (xx, yy, zz, xy), (xz, yz, 0, 0).

struct ContactParams {
    n: u32,
    kc0: u32,            // the first slot's offset in `work`, in entries
    stiffness: f32,
    _pad: u32,
}

@group(0) @binding(0) var<uniform> cp: ContactParams;
@group(0) @binding(1) var<storage, read> force: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> work: array<vec4<f32>>;

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let i = item_index(gid, nwg);
    if i >= cp.n {
        return;
    }
    let f = force[i].xyz;
    let len = sqrt(dot3(f, f));
    if len > 0.0 {
        let u = f / len;
        let k = cp.stiffness;
        // k·(n·n.x, n·n.y, n·n.z) by columns, as glam's Mat3::from_cols and its scaling.
        let a = k * vec4<f32>(u.x * u.x, u.y * u.y, u.z * u.z, u.y * u.x);
        let b = k * vec4<f32>(u.z * u.x, u.z * u.y, 0.0, 0.0);
        work[cp.kc0 + i] += a;
        work[cp.kc0 + cp.n + i] += b;
    }
}
