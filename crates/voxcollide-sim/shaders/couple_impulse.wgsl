// A surface contact's push is inelastic (the CPU's `inelastic_impulses` in
// src/integrator/implicit.rs): after the step's update, where a vertex and its point on the
// partner's surface separate along a coupling the solve kept, an impulse between them (in their
// reduced mass, momentum kept) leaves them none of that speed. Each coupling's impulse reads
// the velocities the couplings before it left, so one invocation walks one contact's couplings
// in order, and the contacts' passes run in contact order: the CPU's order.

@group(0) @binding(0) var<uniform> rp: RelativeParams;
@group(0) @binding(1) var<storage, read> couplings: array<Coupling>;
@group(0) @binding(2) var<storage, read> entries: array<vec2<u32>>;   // (vertex, weight's bits)
@group(0) @binding(3) var<storage, read> info_a: array<vec4<f32>>;    // w: the vertex's mode
@group(0) @binding(4) var<storage, read> info_b: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read> in_solve: array<u32>;
@group(0) @binding(6) var<storage, read_write> vel_a: array<vec4<f32>>;   // w: the inverse mass
@group(0) @binding(7) var<storage, read_write> vel_b: array<vec4<f32>>;

// Vertex v's inverse mass in body a (`on_a`) or b: 0 where it is held.
fn inverse(on_a: bool, v: u32) -> f32 {
    if on_a {
        return select(0.0, vel_a[v].w, u32(info_a[v].w) == MODE_FREE);
    }
    return select(0.0, vel_b[v].w, u32(info_b[v].w) == MODE_FREE);
}

fn velocity(on_a: bool, v: u32) -> vec3<f32> {
    if on_a {
        return vel_a[v].xyz;
    }
    return vel_b[v].xyz;
}

fn kick(on_a: bool, v: u32, dv: vec3<f32>) {
    if on_a {
        vel_a[v] = vec4<f32>(vel_a[v].xyz + dv, vel_a[v].w);
    } else {
        vel_b[v] = vec4<f32>(vel_b[v].xyz + dv, vel_b[v].w);
    }
}

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    if item_index(gid, nwg) != 0u {
        return;
    }
    for (var k = rp.first; k < rp.first + rp.count; k++) {
        let c = couplings[k];
        if c.terms.y <= 0.0 || in_solve[k] == 0u {
            continue;
        }
        let n = c.normal.xyz;
        let point_on_a = c.range.w == 1u;
        var away = 0.0;
        var compliance = 0.0;
        for (var e = c.range.x; e < c.range.y; e++) {
            let v = entries[e].x;
            let w = bitcast<f32>(entries[e].y);
            away += w * dot3(n, velocity(point_on_a, v));
            compliance += w * w * inverse(point_on_a, v);
        }
        for (var e = c.range.y; e < c.range.z; e++) {
            let t = entries[e].x;
            let w = bitcast<f32>(entries[e].y);
            away -= w * dot3(n, velocity(!point_on_a, t));
            compliance += w * w * inverse(!point_on_a, t);
        }
        if away <= 0.0 || compliance <= 0.0 {
            continue;
        }
        // (A kick depends on its vertex's weight and mass only: applied as it is made.)
        let impulse = (away / compliance) * n;
        for (var e = c.range.x; e < c.range.y; e++) {
            let v = entries[e].x;
            let w = bitcast<f32>(entries[e].y);
            kick(point_on_a, v, -(w * inverse(point_on_a, v)) * impulse);
        }
        for (var e = c.range.y; e < c.range.z; e++) {
            let t = entries[e].x;
            let w = bitcast<f32>(entries[e].y);
            kick(!point_on_a, t, (w * inverse(!point_on_a, t)) * impulse);
        }
    }
}
