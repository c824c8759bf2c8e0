// Shared by the simulation passes: a body's step parameters and f32 helpers written in the same
// order as the CPU twin (src/sim/body.rs). Keep SimParams in sync with GpuSimParams in
// src/sim/gpu.rs.

const WORKGROUP_SIZE: u32 = 64u;
const MODE_FREE: u32 = 0u;
const MODE_PINNED: u32 = 1u;
const MODE_DRIVEN: u32 = 2u;

struct SimParams {
    drive: vec4<f32>,      // xyz: offset of driven vertices from their rest positions
    turn_x: vec4<f32>,     // xyz: the columns of their rotation; turn_x.w: 1 if turned at all
    turn_y: vec4<f32>,
    turn_z: vec4<f32>,
    dt: f32,
    rest_scale: f32,
    pressure: f32,
    floor: f32,
    damping: f32,
    spring_damping: f32,
    stiffening: f32,
    v_max: f32,
    n: u32,
    tri_base: u32,         // where the triangle lists start in `adjacency`
    step: u32,
    tri_count: u32,
    fill_volume: f32,      // > 0: a fill of this volume (the pressure is the volume pass's)
    fill_bulk: f32,
    fill_hold: f32,        // > 0: per step, the held pressure's growth per relative deficit (over fill_bulk)
    tets: u32,             // the body's tetrahedra (0: springs alone; elements.wgsl)
    mu: f32,               // their Lamé μ, λ' = λ + μ and α = 1 + μ/λ'
    lambda: f32,
    alpha: f32,
    _pad1: u32,
    gravity: vec4<f32>,    // xyz: the acceleration of gravity; w: 1 where there is any
}

fn item_index(gid: vec3<u32>, nwg: vec3<u32>) -> u32 {
    return gid.x + gid.y * nwg.x * WORKGROUP_SIZE;
}

fn is_finite_f32(x: f32) -> bool {
    return (bitcast<u32>(x) & 0x7f800000u) != 0x7f800000u;
}

fn dot3(u: vec3<f32>, v: vec3<f32>) -> f32 {
    return u.x * v.x + u.y * v.y + u.z * v.z;
}

fn cross3(u: vec3<f32>, v: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(u.y * v.z - u.z * v.y, u.z * v.x - u.x * v.z, u.x * v.y - u.y * v.x);
}
