// The surface contact's step on the device after its search (docs/contacts.md, "The search on
// the device"), for bodies that show their own surface: what the CPU's `SurfaceContact::step`
// does with each side's hits (src/contact/surface.rs), pass by pass, to the bit.
//
// Per side (one body's points probing the other's surface), in this order:
//   `partner_moved`  the partner's largest move since the last step (`Side::age`);
//   `age`            each probe's own move plus that, and the positions kept for the next step;
//   (the search, shaders/surface_search.wgsl)
//   `confirm`        a doubtful hit checked by the winding number and dropped outside (`confirm`);
//                    whether each probe is inside, and the way it was pushed out (its entry);
//   `count`, `scan`, `scatter`  per partner vertex, the hits listed on its triangles (probe,
//                    corner): the pushes, and those within the margin;
// then per body `gather`: each vertex's force summed in the CPU's order (the first side's pushes
// in probe order, then the second's), zero where the vertex is held.

struct Side {
    n_probes: u32,
    n_partner: u32,
    first: u32,          // 1 at the first step: nothing has moved yet
    moved_at: u32,       // where in `scratch` the probes' moves start (f32 bits)
    inside_at: u32,      // the probes' inside flags
    count_at: u32,       // per partner vertex the pushes on it, then their starts (n_partner + 1)
    cursor_at: u32,      // per partner vertex, the next free place
    keys_at: u32,        // 3·probe + corner of each push, by partner vertex
    stiffness: f32,
    gap: f32,
    reach: f32,
    n_triangles: u32,    // the partner's
}


@group(0) @binding(0) var<uniform> side: Side;
@group(0) @binding(1) var<storage, read> probes: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> partner: array<vec4<f32>>;
// The probes' positions at the last step, then the partner's.
@group(0) @binding(3) var<storage, read_write> prev: array<vec4<f32>>;
// [0]: the partner's largest squared move (f32 bits); then the regions of `Side`.
@group(0) @binding(4) var<storage, read_write> scratch: array<atomic<u32>>;
@group(0) @binding(5) var<storage, read_write> hits: array<SurfaceHit>;
// The partner's triangles (3 corners each) from word 0: the search's topology.
@group(0) @binding(6) var<storage, read> topology: array<u32>;

const PI: f32 = 3.14159265358979323846264338327950288;

fn length3(v: vec3<f32>) -> f32 {
    return sqrt(dot3(v, v));
}

@compute @workgroup_size(WORKGROUP_SIZE)
fn partner_moved(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let j = item_index(gid, nwg);
    if j >= side.n_partner {
        return;
    }
    let q = partner[j];
    if side.first == 0u {
        let d = q.xyz - prev[side.n_probes + j].xyz;
        let d2 = dot3(d, d);
        // (`f32::max` passes a NaN over; the bits of the others order as the numbers do.)
        if bitcast<u32>(d2) <= 0x7f800000u {
            atomicMax(&scratch[0], bitcast<u32>(d2));
        }
    }
    prev[side.n_probes + j] = q;
}

@compute @workgroup_size(WORKGROUP_SIZE)
fn age(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let k = item_index(gid, nwg);
    if k >= side.n_probes {
        return;
    }
    let p = probes[k];
    var moved = 0.0;
    if side.first == 0u {
        moved = length3(p.xyz - prev[k].xyz) + sqrt(bitcast<f32>(atomicLoad(&scratch[0])));
    }
    atomicStore(&scratch[side.moved_at + k], bitcast<u32>(moved));
    prev[k] = p;
    // The motion comes off the probe's clearance (`Side::age`).
    hits[k].clear = hits[k].clear - moved;
}

// Half the solid angle of triangle t seen from p (Van Oosterom and Strackee), in f32: the CPU
// sums it in f64 through a hierarchy, so the two agree on the side of a point but not to the
// bit, and a doubtful hit is deep or sudden, far from the surface the sum jumps at.
fn half_solid_angle(t: u32, p: vec3<f32>) -> f32 {
    let a = partner[topology[3u * t]].xyz - p;
    let b = partner[topology[3u * t + 1u]].xyz - p;
    let c = partner[topology[3u * t + 2u]].xyz - p;
    let la = length3(a);
    let lb = length3(b);
    let lc = length3(c);
    let num = dot3(a, cross3(b, c));
    let den = la * lb * lc + dot3(a, b) * lc + dot3(a, c) * lb + dot3(b, c) * la;
    return atan2(num, den);
}

// Whether p is inside the partner's closed surface: its winding number above one half, summed
// over every triangle (outside the triangles' box: not inside, as `ClosedSurface::contains`).
fn inside_partner(p: vec3<f32>) -> bool {
    if !(is_finite_f32(p.x) && is_finite_f32(p.y) && is_finite_f32(p.z)) {
        return false;
    }
    var lo = vec3<f32>(3.0e38);
    var hi = vec3<f32>(-3.0e38);
    var sum = 0.0;
    for (var t = 0u; t < side.n_triangles; t++) {
        for (var c = 0u; c < 3u; c++) {
            let q = partner[topology[3u * t + c]].xyz;
            lo = min(lo, q);
            hi = max(hi, q);
        }
        sum = sum + half_solid_angle(t, p);
    }
    if any(p < lo) || any(p > hi) {
        return false;
    }
    return sum > PI;
}

@compute @workgroup_size(WORKGROUP_SIZE)
fn confirm(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let k = item_index(gid, nwg);
    if k >= side.n_probes {
        return;
    }
    var hit = hits[k];
    let was_inside = atomicLoad(&scratch[side.inside_at + k]) == 1u;
    if hit.found == 1u {
        let depth = hit.normal.w;
        let inside = depth - side.gap;
        let moved = bitcast<f32>(atomicLoad(&scratch[side.moved_at + k]));
        let deep = side.gap + 0.25 * side.reach;
        let slack = 1e-4 * side.reach;
        let suspect = depth > deep || (inside > 0.0 && !was_inside && inside > moved * 1.001 + slack);
        if suspect && !inside_partner(probes[k].xyz) {
            hit.found = 0u;
        }
    }
    let now_inside = hit.found == 1u && hit.normal.w > side.gap;
    atomicStore(&scratch[side.inside_at + k], select(0u, 1u, now_inside));
    hit.entry = select(vec4<f32>(0.0), vec4<f32>(hit.normal.xyz, 0.0), now_inside);
    hits[k] = hit;
}

// Whether probe k is listed: it pushes (a hit deeper than the gap), or lies within the
// margin (no force; the implicit solve's couplings take it, src/gpu/implicit.rs).
fn listed(k: u32) -> bool {
    return hits[k].found == 1u;
}

@compute @workgroup_size(WORKGROUP_SIZE)
fn count(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let k = item_index(gid, nwg);
    if k >= side.n_probes || !listed(k) {
        return;
    }
    let t = hits[k].triangle;
    for (var c = 0u; c < 3u; c++) {
        atomicAdd(&scratch[side.count_at + topology[3u * t + c]], 1u);
    }
}

var<workgroup> chunk_sums: array<u32, WORKGROUP_SIZE>;

// The counts into their starts, in place (an exclusive prefix sum over n_partner + 1 entries,
// the last the total), by one workgroup: each invocation a run of them.
@compute @workgroup_size(WORKGROUP_SIZE)
fn scan(@builtin(local_invocation_index) lid: u32) {
    let n = side.n_partner + 1u;
    let per = (n + WORKGROUP_SIZE - 1u) / WORKGROUP_SIZE;
    let start = min(lid * per, n);
    let end = min(start + per, n);
    var total = 0u;
    for (var i = start; i < end; i++) {
        total += atomicLoad(&scratch[side.count_at + i]);
    }
    chunk_sums[lid] = total;
    workgroupBarrier();
    var before = 0u;
    for (var l = 0u; l < lid; l++) {
        before += chunk_sums[l];
    }
    for (var i = start; i < end; i++) {
        let c = atomicLoad(&scratch[side.count_at + i]);
        atomicStore(&scratch[side.count_at + i], before);
        before += c;
    }
}

@compute @workgroup_size(WORKGROUP_SIZE)
fn scatter(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let k = item_index(gid, nwg);
    if k >= side.n_probes || !listed(k) {
        return;
    }
    let t = hits[k].triangle;
    for (var c = 0u; c < 3u; c++) {
        let v = topology[3u * t + c];
        let at = atomicLoad(&scratch[side.count_at + v]) + atomicAdd(&scratch[side.cursor_at + v], 1u);
        atomicStore(&scratch[side.keys_at + at], 3u * k + c);
    }
}
