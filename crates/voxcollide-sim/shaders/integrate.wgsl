// Simulation pass 2: semi-implicit Euler for free vertices (kept above the floor), rest
// positions for pinned ones, (turn ·) rest + drive for driven ones; a non-finite position or a runaway
// speed records the first step and vertex where it happened (the modes and the floor: held.wgsl).
// CPU twin: MassSpring::integrate.

@group(0) @binding(0) var<uniform> sim: SimParams;
@group(0) @binding(1) var<storage, read_write> pos: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> vel: array<vec4<f32>>;   // w: 1 / mass, kept
@group(0) @binding(3) var<storage, read> info: array<vec4<f32>>;        // xyz: rest, w: mode
@group(0) @binding(4) var<storage, read> acc: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read_write> status: array<atomic<u32>, 2>; // ~step, ~vertex

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let i = item_index(gid, nwg);
    if i >= sim.n {
        return;
    }
    let mode = u32(info[i].w);
    let rest = info[i].xyz;
    var x = pos[i].xyz;
    var v = vel[i].xyz;
    var m: Moved;
    if mode == MODE_FREE {
        v += sim.dt * acc[i].xyz;
        x += sim.dt * v;
        m = onto_floor(x, v);
    } else {
        m = move_held(mode, rest, x, sim.dt);
    }
    x = m.x;
    v = m.v;
    pos[i] = vec4<f32>(x, 1.0);
    vel[i] = vec4<f32>(v, vel[i].w);
    let finite = is_finite_f32(x.x) && is_finite_f32(x.y) && is_finite_f32(x.z)
        && is_finite_f32(v.x) && is_finite_f32(v.y) && is_finite_f32(v.z);
    if !finite || sqrt(dot3(v, v)) > sim.v_max {
        atomicMax(&status[0], ~sim.step);
        atomicMax(&status[1], ~i);
    }
}
