// The implicit solve's per-tetrahedron passes (one invocation per tetrahedron), composed after
// implicit_solve.wgsl: a tetrahedron's projected stiffness at the step's start, and its share of
// −K times a vector, stored per tetrahedron for the vertices to gather in adjacency order.

fn tetrahedron_product(k: u32, which: u32, s: u32) {
    let t = tet_corners(k);
    store_product(k, which, stiffness_product(load_tangent(k), vget(s, t.x), vget(s, t.y), vget(s, t.z), vget(s, t.w)));
}

// Its projected stiffness at the step's start.
@compute @workgroup_size(64)
fn tangent(at: Invocation) {
    let k = item(at);
    if k < sim.tets {
        let t = tet_corners(k);
        store_tangent(k, tangent_at(deformation(k, pos[t.x].xyz, pos[t.y].xyz, pos[t.z].xyz, pos[t.w].xyz), k));
    }
}

// Its −K·v and −K·Δv_held (the right-hand side's).
@compute @workgroup_size(64)
fn product_rhs(at: Invocation) {
    let k = item(at);
    if k < sim.tets {
        let t = tet_corners(k);
        store_product(k, 0u, stiffness_product(load_tangent(k), vel[t.x].xyz, vel[t.y].xyz, vel[t.z].xyz, vel[t.w].xyz));
        tetrahedron_product(k, 1u, SLOT_HELD);
    }
}

// Its −K·p (the conjugate gradient's).
@compute @workgroup_size(64)
fn product_p(at: Invocation) {
    let k = item(at);
    if k < sim.tets {
        tetrahedron_product(k, 0u, SLOT_P);
    }
}

// Its −K·x (the guess's).
@compute @workgroup_size(64)
fn product_x(at: Invocation) {
    let k = item(at);
    if k < sim.tets {
        tetrahedron_product(k, 0u, SLOT_X);
    }
}
