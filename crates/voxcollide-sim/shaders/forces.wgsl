// Simulation pass 1: the force on every vertex of a body — its springs (nonlinear, damped),
// viscous damping, the internal pressure on its surface triangles, its weight and its contact force —
// summed per vertex in adjacency order (a body's tetrahedra after its springs: elements.wgsl),
// then divided by its mass; the spring law is springs.wgsl's. CPU twin: MassSpring::forces.

@group(0) @binding(0) var<uniform> sim: SimParams;
@group(0) @binding(1) var<storage, read> pos: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> vel: array<vec4<f32>>;       // w: 1 / mass
@group(0) @binding(3) var<storage, read> contact: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read> offsets: array<vec2<u32>>;   // (springs, triangles) CSR
@group(0) @binding(5) var<storage, read> adjacency: array<u32>;       // (other, spring) pairs, then triangles
@group(0) @binding(6) var<storage, read> springs: array<vec2<f32>>;   // (rest, k)
@group(0) @binding(7) var<storage, read> triangles: array<vec4<u32>>;
@group(0) @binding(8) var<storage, read_write> acc: array<vec4<f32>>;
@group(0) @binding(9) var<storage, read> fill: array<f32>;             // [0]: the pressure of a fill
@group(0) @binding(10) var<storage, read> tet_index: array<u32>;       // elements.wgsl
@group(0) @binding(11) var<storage, read> tet_rest: array<vec4<f32>>;
@group(0) @binding(12) var<storage, read> mass: array<f32>;            // what gravity pulls

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let i = item_index(gid, nwg);
    if i >= sim.n {
        return;
    }
    let x = pos[i].xyz;
    let v = vel[i].xyz;
    var f = contact[i].xyz - sim.damping * v;
    let range = vec2<u32>(offsets[i].x, offsets[i + 1u].x);
    for (var e = range.x; e < range.y; e++) {
        let j = adjacency[2u * e];
        let s = springs[adjacency[2u * e + 1u]];
        f += spring_force(x, v, pos[j].xyz, vel[j].xyz, s.x * sim.rest_scale, s.y);
    }
    if sim.tets > 0u {
        f += elements_force(i);
    }
    var pressure = sim.pressure;
    if sim.fill_volume > 0.0 {
        pressure = fill[0];
    }
    if pressure != 0.0 {
        let tris = vec2<u32>(offsets[i].y, offsets[i + 1u].y);
        for (var e = tris.x; e < tris.y; e++) {
            let t = triangles[adjacency[sim.tri_base + e]];
            let a = pos[t.x].xyz;
            let b = pos[t.y].xyz;
            let c = pos[t.z].xyz;
            f += (pressure / 6.0) * cross3(b - a, c - a);
        }
    }
    if sim.gravity.w != 0.0 {
        f += mass[i] * sim.gravity.xyz;
    }
    acc[i] = vec4<f32>(f * vel[i].w, 0.0);
}
