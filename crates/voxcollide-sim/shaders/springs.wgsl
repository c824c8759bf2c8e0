// The paper's spring law, written once for every pass that needs it (forces.wgsl,
// implicit_solve.wgsl): a spring pulls its ends together with k·(L − L0)·(1 + stiffening·s²) along
// it, s = (L − L0)/L0, plus damping along it. CPU twin: src/material/springs.rs, term for term.
// Reads the pass's `sim` (SimParams, sim_common.wgsl) for the body's constants.

// A spring's tension at length `len` (rest length `rest`, stiffness `k`).
fn spring_tension_at(len: f32, rest: f32, k: f32) -> f32 {
    let strain = (len - rest) / rest;
    return k * (len - rest) * (1.0 + sim.stiffening * strain * strain);
}

// Its tangent stiffness at that length: d tension / dL.
fn spring_tangent_at(len: f32, rest: f32, k: f32) -> f32 {
    let strain = (len - rest) / rest;
    return k * (1.0 + 3.0 * sim.stiffening * strain * strain);
}

// The force of one spring on its end `x` (velocity `v`) from the other end `y` (velocity `w`).
fn spring_force(x: vec3<f32>, v: vec3<f32>, y: vec3<f32>, w: vec3<f32>, rest: f32, k: f32) -> vec3<f32> {
    let d = y - x;
    let len = sqrt(dot3(d, d));
    if len < 1e-12 {
        return vec3<f32>(0.0);
    }
    let u = d / len;
    let tension = spring_tension_at(len, rest, k);
    let damping = sim.spring_damping * dot3(w - v, u);
    return (tension + damping) * u;
}

// The same spring at rest (no damping), its (rest, k) in `s`, scaled by the step's rest scale.
fn spring_tension(x: vec3<f32>, y: vec3<f32>, s: vec2<f32>) -> vec3<f32> {
    let d = y - x;
    let len = sqrt(dot3(d, d));
    if len < 1e-12 {
        return vec3<f32>(0.0);
    }
    let u = d / len;
    return spring_tension_at(len, s.x * sim.rest_scale, s.y) * u;
}
