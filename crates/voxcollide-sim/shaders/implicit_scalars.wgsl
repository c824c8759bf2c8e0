// The implicit solve's scalars, composed after implicit_solve.wgsl: each pass is one workgroup
// that sums the partials of `red`'s columns into the solve's scalars. `scalars_a` and
// `scalars_gp` sum one body's partials into its own scalars (run per body); the others sum every
// body's into the joint solve's (run once).

// g·v, g·Δv_held and the residual's sums (a body's own).
@compute @workgroup_size(64)
fn scalars_a(at: Invocation) {
    let lane = at.lane;
    let gv = own_sum(COL_GP, lane);
    let gh = own_sum(COL_PAP, lane);
    let net = own_sum(COL_NET, lane);
    let gross = own_sum(COL_GROSS, lane);
    if lane == 0u {
        set_body_scalar(B_GV, gv);
        set_body_scalar(B_GHELD, gh);
        set_body_scalar(B_NET2, net);
        set_body_scalar(B_GROSS2, gross);
        // `gp` reads x while S_DONE is negative (the guess's g·x).
        set_scalar(S_DONE, -1.0);
    }
}

// |b|, |b − A·x| and whether the guess is used.
@compute @workgroup_size(64)
fn scalars_b(at: Invocation) {
    let lane = at.lane;
    let bb = column_sum(COL_RR, lane);
    let left = column_sum(COL_LEFT, lane);
    if lane == 0u {
        set_scalar(S_NORM_B2, bb);
        set_scalar(S_LEFT2, left);
        // From the guess where it leaves less to solve than 0 does.
        set_scalar(S_USE_GUESS, select(0.0, 1.0, ip.guess_scale > 0.0 && left < bb));
        // |r| against tol·|b| unsquared, as the CPU compares them (tol²·|b|² would leave
        // f32's normal range near rest in small units).
        set_scalar(S_TARGET, ip.tolerance * sqrt(bb));
        // The first iteration always runs, as on the CPU (|r| is taken as |b| at the start).
        set_scalar(S_RR, bb);
        set_scalar(S_ITERATIONS, 0.0);
        set_scalar(S_DONE, select(0.0, 1.0, bb == 0.0));
        set_scalar(S_ALPHA, 0.0);
        set_scalar(S_BETA, 0.0);
    }
}

// r·z at the start.
@compute @workgroup_size(64)
fn scalars_c(at: Invocation) {
    let lane = at.lane;
    let rz = column_sum(COL_RZ, lane);
    if lane == 0u {
        set_scalar(S_RZ, rz);
    }
}

// g·p (a body's own).
@compute @workgroup_size(64)
fn scalars_gp(at: Invocation) {
    let lane = at.lane;
    let gp = own_sum(COL_GP, lane);
    if lane == 0u {
        set_body_scalar(B_GP, gp);
    }
}

// α, or done.
@compute @workgroup_size(64)
fn scalars_alpha(at: Invocation) {
    let lane = at.lane;
    let pap = column_sum(COL_PAP, lane);
    if lane == 0u {
        var alpha = 0.0;
        var done = scalar(S_DONE);
        if done == 0.0 {
            // The CPU's loop test (iterations left, residual above the target), then a
            // positive curvature (a NaN stops it too).
            if scalar(S_ITERATIONS) >= ip.max_iterations || sqrt(scalar(S_RR)) <= scalar(S_TARGET) || !(pap > 0.0) {
                done = 1.0;
            } else {
                alpha = scalar(S_RZ) / pap;
            }
        }
        set_scalar(S_DONE, done);
        set_scalar(S_ALPHA, alpha);
    }
}

// β, |r| and the iteration count.
@compute @workgroup_size(64)
fn scalars_beta(at: Invocation) {
    let lane = at.lane;
    let rr = column_sum(COL_RR, lane);
    let rz = column_sum(COL_RZ, lane);
    if lane == 0u && scalar(S_DONE) == 0.0 {
        set_scalar(S_RR, rr);
        set_scalar(S_BETA, rz / scalar(S_RZ));
        set_scalar(S_RZ, rz);
        let iterations = scalar(S_ITERATIONS) + 1.0;
        set_scalar(S_ITERATIONS, iterations);
        // The CPU's loop test, at once (so that the host sees a finished solve in the batch
        // it finished in); a curvature that is not positive is ALPHA's to find.
        if iterations >= ip.max_iterations || sqrt(rr) <= scalar(S_TARGET) {
            set_scalar(S_DONE, 1.0);
        }
    }
}

// The farthest move.
@compute @workgroup_size(64)
fn scalars_far(at: Invocation) {
    let lane = at.lane;
    let far = column_max(COL_FAR, lane);
    if lane == 0u {
        set_scalar(S_FARTHEST, far);
    }
}
