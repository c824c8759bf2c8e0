// The implicit solve's system, per vertex, composed after implicit_solve.wgsl: the step's
// forces and residual terms, the floor's rows, and the right-hand side with the
// preconditioner's blocks and the guess.

fn prepare_vertex(i: u32) -> vec2<f32> {
    let x = pos[i].xyz;
    let v = vel[i].xyz;
    let free = is_free(i);
    var pressure = sim.pressure;
    if sim.fill_volume > 0.0 {
        pressure = fill[0];
    }
    // The forces (CPU: MassSpring::forces), and the residual's at rest (MassSpring::residual).
    var f = contact[i].xyz - sim.damping * v;
    var rest_f = contact[i].xyz;
    var gross = sqrt(dot3(contact[i].xyz, contact[i].xyz));
    var outside = gross;      // contact, pressure and weight: the loads (under gravity)
    let range = vec2<u32>(offsets[i].x, offsets[i + 1u].x);
    for (var e = range.x; e < range.y; e++) {
        let j = adjacency[2u * e];
        let s = springs[adjacency[2u * e + 1u]];
        let y = pos[j].xyz;
        f += spring_force(x, v, y, vel[j].xyz, s.x * sim.rest_scale, s.y);
        let t = spring_tension(x, y, s);
        rest_f += t;
        gross += sqrt(dot3(t, t));
    }
    if sim.tets > 0u {
        var fe = vec3<f32>(0.0);
        let tets = tet_range(i);
        for (var e = tets.x; e < tets.y; e++) {
            let kc = tet_index[e];
            let t = tet_corner_force(kc / 4u, kc % 4u);
            fe += t;
            gross += sqrt(dot3(t, t));
        }
        f += fe;
        rest_f += fe;
    }
    var g = vec3<f32>(0.0);
    let tris = vec2<u32>(offsets[i].y, offsets[i + 1u].y);
    for (var e = tris.x; e < tris.y; e++) {
        let t = triangles[adjacency[sim.tri_base + e]];
        let c = (1.0 / 6.0) * cross3(pos[t.y].xyz - pos[t.x].xyz, pos[t.z].xyz - pos[t.x].xyz);
        g += c;
        if pressure != 0.0 {
            let p = (pressure / 6.0) * cross3(pos[t.y].xyz - pos[t.x].xyz, pos[t.z].xyz - pos[t.x].xyz);
            f += p;
            rest_f += p;
            gross += sqrt(dot3(p, p));
            outside += sqrt(dot3(p, p));
        }
    }
    if sim.gravity.w != 0.0 {
        let w = mass[i] * sim.gravity.xyz;
        f += w;
        rest_f += w;
        gross += sqrt(dot3(w, w));
        outside += sqrt(dot3(w, w));
    }
    if x.z <= sim.floor && rest_f.z < 0.0 {
        rest_f.z = 0.0;
    }
    let floor_row = free && x.z <= sim.floor && f.z < 0.0;
    work[slot(SLOT_F, i)] = vec4<f32>(f, select(0.0, 1.0, floor_row));
    vput(SLOT_G, i, g);
    let mode = u32(info[i].w);
    var held = vec3<f32>(0.0);
    if mode == MODE_PINNED {
        held = -v;
    } else if mode == MODE_DRIVEN {
        held = (driven_target(info[i].xyz) - x) / ip.h - v;
    }
    vput(SLOT_HELD, i, held);
    // Under gravity the residual is judged against the loads that act: each free vertex's
    // contact, pressure and weight, and each held one's reaction (CPU: MassSpring::residual).
    if sim.gravity.w != 0.0 {
        if free {
            return vec2<f32>(dot3(rest_f, rest_f), outside * outside);
        }
        return vec2<f32>(0.0, dot3(rest_f, rest_f));
    }
    if free {
        return vec2<f32>(dot3(rest_f, rest_f), gross * gross);
    }
    return vec2<f32>(0.0);
}

fn rhs_vertex(i: u32) -> f32 {
    let h = ip.h;
    let free = is_free(i);
    // The preconditioner's block: the diagonal of A.
    let kc = contact_k(i);
    let cd = contact_damping(i, kc);
    let diagonal = 1.0 / vel[i].w + h * sim.damping;
    var b = mat3x3<f32>(vec3<f32>(diagonal, 0.0, 0.0), vec3<f32>(0.0, diagonal, 0.0), vec3<f32>(0.0, 0.0, diagonal));
    b += h * h * kc + h * cd;
    let range = vec2<u32>(offsets[i].x, offsets[i + 1u].x);
    for (var e = range.x; e < range.y; e++) {
        let j = adjacency[2u * e];
        let s = blocks(i, j, springs[adjacency[2u * e + 1u]]);
        let a = h * h * s.across;
        let c = h * h * s.along + h * sim.spring_damping;
        b += mat3x3<f32>(vec3<f32>(a, 0.0, 0.0), vec3<f32>(0.0, a, 0.0), vec3<f32>(0.0, 0.0, a)) + c * outer(s.u);
    }
    if ip.fill_k > 0.0 {
        b += (h * h * ip.fill_k) * outer(vget(SLOT_G, i));
    }
    if sim.tets > 0u {
        let tets = tet_range(i);
        for (var e = tets.x; e < tets.y; e++) {
            let kc = tet_index[e];
            b += (h * h) * diagonal_block(load_tangent(kc / 4u), kc % 4u);
        }
    }
    if ip.coupled != 0u {
        b += symmetric(SLOT_E0, SLOT_E1, i);
    }
    var inv = inverse3(b);
    if !(finite3(inv[0]) && finite3(inv[1]) && finite3(inv[2])) {
        let d = 1.0 / diagonal;
        inv = mat3x3<f32>(vec3<f32>(d, 0.0, 0.0), vec3<f32>(0.0, d, 0.0), vec3<f32>(0.0, 0.0, d));
    }
    vput(SLOT_P0, i, inv[0]);
    vput(SLOT_P1, i, inv[1]);
    vput(SLOT_P2, i, inv[2]);
    // b = h·(f − C_c·v − h·(−K)·v) − A·Δv_held on the free rows (velocities as the floor left them).
    var rhs = vec3<f32>(0.0);
    var x = vec3<f32>(0.0);
    if free {
        // −K·v: the stiff product of the velocities (they live in `vel`, not `work`: gathered here).
        let v = vel[i].xyz;
        var kv = kc * v;
        var a_held = vec3<f32>(0.0);
        let hi = vget(SLOT_HELD, i);
        for (var e = range.x; e < range.y; e++) {
            let j = adjacency[2u * e];
            let s = blocks(i, j, springs[adjacency[2u * e + 1u]]);
            let d = v - vel[j].xyz;
            kv += s.across * d + (s.along * dot3(s.u, d)) * s.u;
            let dh = hi - vget(SLOT_HELD, j);
            let a = h * h * s.across;
            let c = h * h * s.along + h * sim.spring_damping;
            a_held += a * dh + (c * dot3(s.u, dh)) * s.u;
        }
        a_held += (1.0 / vel[i].w + h * sim.damping) * hi + (h * h * kc + h * cd) * hi;
        if sim.tets > 0u {
            kv += gather_product(i, 0u);
            a_held += (h * h) * gather_product(i, 1u);
        }
        if ip.fill_k > 0.0 {
            kv += (ip.fill_k * body_scalar(B_GV)) * vget(SLOT_G, i);
            a_held += (h * h * ip.fill_k * body_scalar(B_GHELD)) * vget(SLOT_G, i);
        }
        rhs = h * (vget(SLOT_F, i) - cd * v - h * kv) - a_held + coupling(i);
        if ip.guess_scale > 0.0 {
            x = filtered(i, ip.guess_scale * vget(SLOT_X, i));
        }
    }
    vput(SLOT_B, i, rhs);
    vput(SLOT_X, i, x);
    let r = filtered(i, rhs);
    return dot3(r, r);
}

// Forces, floor rows, the fill's gradient, the held Δv and the residual's terms.
@compute @workgroup_size(64)
fn prepare(at: Invocation) {
    let i = item(at);
    let wg = group_index(at);
    let lane = at.lane;
    let live = i < sim.n;
    var terms = vec2<f32>(0.0);
    if live {
        terms = prepare_vertex(i);
    }
    partial_sum(COL_NET, wg, lane, terms.x);
    partial_sum(COL_GROSS, wg, lane, terms.y);
}

// The floor rows' vertical speed to 0; g·v and g·Δv_held.
@compute @workgroup_size(64)
fn floor_rows(at: Invocation) {
    let i = item(at);
    let wg = group_index(at);
    let lane = at.lane;
    let live = i < sim.n;
    var gv = 0.0;
    var gh = 0.0;
    if live {
        if on_floor(i) {
            vel[i] = vec4<f32>(vel[i].x, vel[i].y, 0.0, vel[i].w);
        }
        let g = vget(SLOT_G, i);
        gv = dot3(g, vel[i].xyz);
        gh = dot3(g, vget(SLOT_HELD, i));
    }
    partial_sum(COL_GP, wg, lane, gv);
    partial_sum(COL_PAP, wg, lane, gh);
}

// K·v, A·Δv_held, the right-hand side, the preconditioner and the guess.
@compute @workgroup_size(64)
fn rhs(at: Invocation) {
    let i = item(at);
    let wg = group_index(at);
    let lane = at.lane;
    let live = i < sim.n;
    var bb = 0.0;
    if live {
        bb = rhs_vertex(i);
    }
    partial_sum(COL_RR, wg, lane, bb);
}
