// The implicit solve's conjugate gradient, per vertex, composed after implicit_solve.wgsl; its
// scalars (α, β, whether it is done) are implicit_scalars.wgsl's.

// b − A·x from the guess.
@compute @workgroup_size(64)
fn guess(at: Invocation) {
    let i = item(at);
    let wg = group_index(at);
    let lane = at.lane;
    let live = i < sim.n;
    // Needs g·x for a fill: taken as the body's B_GP, written by `scalars_gp` over x.
    var left2 = 0.0;
    if live {
        var ax = vec3<f32>(0.0);
        if is_free(i) {
            ax = filtered(i, apply_row(i, SLOT_X, body_scalar(B_GP), false) + coupling(i));
        }
        let left = filtered(i, vget(SLOT_B, i)) - ax;
        vput(SLOT_R, i, left);
        left2 = dot3(left, left);
    }
    partial_sum(COL_LEFT, wg, lane, left2);
}

// r, z = P·r, p = z.
@compute @workgroup_size(64)
fn start(at: Invocation) {
    let i = item(at);
    let wg = group_index(at);
    let lane = at.lane;
    let live = i < sim.n;
    var rz = 0.0;
    if live {
        var r = filtered(i, vget(SLOT_B, i));
        if scalar(S_USE_GUESS) != 0.0 {
            r = vget(SLOT_R, i);
        } else {
            vput(SLOT_X, i, vec3<f32>(0.0));
        }
        vput(SLOT_R, i, r);
        let z = precondition(i, r);
        vput(SLOT_Z, i, z);
        vput(SLOT_P, i, z);
        rz = dot3(r, z);
    }
    partial_sum(COL_RZ, wg, lane, rz);
}

// g·p (a fill's rank-one term).
@compute @workgroup_size(64)
fn gp(at: Invocation) {
    let i = item(at);
    let wg = group_index(at);
    let lane = at.lane;
    let live = i < sim.n;
    // g·p, or g·x for `guess` (x while S_DONE is negative, as `scalars_a` leaves it).
    var gp = 0.0;
    if live {
        var s = SLOT_P;
        if scalar(S_DONE) < 0.0 {
            s = SLOT_X;
        }
        gp = dot3(vget(SLOT_G, i), vget(s, i));
    }
    partial_sum(COL_GP, wg, lane, gp);
}

// A·p and p·A·p.
@compute @workgroup_size(64)
fn apply(at: Invocation) {
    let i = item(at);
    let wg = group_index(at);
    let lane = at.lane;
    let live = i < sim.n;
    var pap = 0.0;
    if live {
        var ap = vec3<f32>(0.0);
        if is_free(i) {
            ap = filtered(i, apply_row(i, SLOT_P, body_scalar(B_GP), false) + coupling(i));
        }
        vput(SLOT_AP, i, ap);
        pap = dot3(vget(SLOT_P, i), ap);
    }
    partial_sum(COL_PAP, wg, lane, pap);
}

// x += α·p, r −= α·A·p, z = P·r, r·r and r·z.
@compute @workgroup_size(64)
fn update(at: Invocation) {
    let i = item(at);
    let wg = group_index(at);
    let lane = at.lane;
    let live = i < sim.n;
    var rr = 0.0;
    var rz = 0.0;
    // Done: nothing moves (where a NaN curvature stopped it, `0·p` would not be 0).
    if live && scalar(S_DONE) == 0.0 {
        let alpha = scalar(S_ALPHA);
        vput(SLOT_X, i, vget(SLOT_X, i) + alpha * vget(SLOT_P, i));
        let r = vget(SLOT_R, i) - alpha * vget(SLOT_AP, i);
        vput(SLOT_R, i, r);
        let z = precondition(i, r);
        vput(SLOT_Z, i, z);
        rr = dot3(r, r);
        rz = dot3(r, z);
    }
    partial_sum(COL_RR, wg, lane, rr);
    partial_sum(COL_RZ, wg, lane, rz);
}

// p = z + β·p.
@compute @workgroup_size(64)
fn direction(at: Invocation) {
    let i = item(at);
    let live = i < sim.n;
    if live && scalar(S_DONE) == 0.0 {
        vput(SLOT_P, i, vget(SLOT_Z, i) + scalar(S_BETA) * vget(SLOT_P, i));
    }
}
