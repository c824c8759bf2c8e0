// The implicit solve's end, per vertex, composed after implicit_solve.wgsl: the new velocity and
// the farthest move (to split or scale the step), then the update.

fn move_vertex(i: u32) {
    let h = ip.h;
    let mode = u32(info[i].w);
    var x = pos[i].xyz;
    var v = vel[i].xyz;
    if mode == MODE_FREE {
        v = ip.scale * vget(SLOT_T, i);
        x += h * v;
        // A voxel-model contact's push is inelastic: no speed left away from what pushes.
        let push = sqrt(dot3(contact[i].xyz, contact[i].xyz));
        let kc = contact_k(i);
        if push > 0.0 && kc[0].x + kc[1].y + kc[2].z > 0.0 {
            let n = contact[i].xyz / push;
            let away = dot3(v, n);
            if away > 0.0 {
                v -= away * n;
            }
        }
        let m = onto_floor(x, v);
        x = m.x;
        v = m.v;
    } else {
        let m = move_held(mode, info[i].xyz, x, h);
        x = m.x;
        v = m.v;
    }
    pos[i] = vec4<f32>(x, 1.0);
    vel[i] = vec4<f32>(v, vel[i].w);
    if !finite3(x) || !finite3(v) || sqrt(dot3(v, v)) > sim.v_max {
        atomicMax(&status[0], ~sim.step);
        atomicMax(&status[1], ~i);
    }
}

// The new velocity and the farthest move.
@compute @workgroup_size(64)
fn farthest(at: Invocation) {
    let i = item(at);
    let wg = group_index(at);
    let lane = at.lane;
    let live = i < sim.n;
    var far = 0.0;
    if live {
        var dv = vget(SLOT_HELD, i);
        if is_free(i) {
            dv = vget(SLOT_X, i);
        }
        let v = vel[i].xyz + dv;
        vput(SLOT_T, i, v);
        if is_free(i) {
            far = ip.h * sqrt(dot3(v, v));
        }
    }
    partial_max(COL_FAR, wg, lane, far);
}

// The update, the modes, the floor and the contacts' inelastic push.
@compute @workgroup_size(64)
fn advance(at: Invocation) {
    let i = item(at);
    let live = i < sim.n;
    if live {
        move_vertex(i);
    }
}
