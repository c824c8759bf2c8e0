// The end of a step for a vertex that is not free, and the floor under a free one, as both
// integrators do them (integrate.wgsl, implicit_move.wgsl). CPU twin: src/integrator/mod.rs
// (move_held, onto_floor) and body::driven_target. Reads the pass's `sim` (SimParams).

// Where a driven vertex resting at `rest` is put: (turn ·) rest + drive, column by column.
fn driven_target(rest: vec3<f32>) -> vec3<f32> {
    if sim.turn_x.w != 0.0 {
        return sim.turn_x.xyz * rest.x + sim.turn_y.xyz * rest.y + sim.turn_z.xyz * rest.z + sim.drive.xyz;
    }
    return rest + sim.drive.xyz;
}

// A vertex's position and velocity at the end of a step.
struct Moved {
    x: vec3<f32>,
    v: vec3<f32>,
}

// A pinned vertex back at `rest` and still; a driven one at its target, at the speed that took
// it there from `x` over `dt`.
fn move_held(mode: u32, rest: vec3<f32>, x: vec3<f32>, dt: f32) -> Moved {
    if mode == MODE_PINNED {
        return Moved(rest, vec3<f32>(0.0));
    }
    let t = driven_target(rest);
    return Moved(t, (t - x) / dt);
}

// A free vertex below the floor put on it, moving up at most.
fn onto_floor(x: vec3<f32>, v: vec3<f32>) -> Moved {
    var m = Moved(x, v);
    if x.z < sim.floor {
        m.x.z = sim.floor;
        m.v.z = max(v.z, 0.0);
    }
    return m;
}
