// One coupling of a surface contact in the implicit solve, as couple_build.wgsl writes it and
// couple.wgsl, couple_lists.wgsl and couple_impulse.wgsl read it (src/gpu/implicit.rs,
// `Couplings`; the CPU's `Coupling`).
struct Coupling {
    normal: vec4<f32>,   // xyz: the push's direction (unit); w: its stiffness k
    terms: vec4<f32>,    // x: its critical damping d; y: its depth (gap − s at the step's start;
                         // > 0: pushed now)
    range: vec4<u32>,    // x: its first entry; y: the partner's first; z: the end; w: 1 where
                         // the pushed point is a's (the triangle then b's)
}

// One contact's couplings as couple.wgsl and couple_impulse.wgsl take them. Keep in sync with
// `RelativeParams` in src/gpu/implicit.rs.
struct RelativeParams {
    h: f32,
    round: u32,       // MODE_ARRIVE: the solve's round (1: pairs join and leave; later: join)
    first: u32,       // the contact's first coupling
    count: u32,       // its couplings
    n_a: u32,         // the vertices of the contact's bodies a and b
    n_b: u32,
    _pad0: u32,
    _pad1: u32,
}
