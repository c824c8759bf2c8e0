// The surface contact's search on the device (docs/contacts.md, "The search on the device"): each
// probing point's nearest triangle of the partner's surface within the cutoff, found through the
// voxel model. The partner's points are binned by the core's passes (its `Params`, `State`,
// slot starts and sorted points, `voxcollide::GpuCollision::record_binning`, composed from its
// `common.wgsl`); `longest_edge` measures the surface's longest edge now; and each probe walks
// the block of voxels about its own out to `near` (the cutoff plus that edge: every triangle
// within the cutoff has a corner that near), k voxels each way (one, while the surface has not
// stretched past the voxel it was binned for), to the triangles at the points binned there
// that lie within `near` of it. Then the push as the CPU's
// `Side::hit` finds it (src/contact/surface.rs): the nearest feature's pseudo-normal, the signed
// distance, the direction. Every float operation is written in the CPU's order (glam's `Vec3`
// methods spelled out), so that both give the same bits.

struct Search {
    n_probes: u32,
    tri_at: u32,        // where in `topology` the triangles start (3 corners each)
    nbr_at: u32,        // the triangle across each edge (3 each; NONE: none)
    off_at: u32,        // per partner point, where its triangles start in the list below (CSR)
    adj_at: u32,        // the triangles at each point
    cutoff: f32,        // max(reach, gap + margin): no push from farther
    reach: f32,
    gap: f32,
    margin: f32,
    voxel: f32,         // the binning's
    n_triangles: u32,   // the partner's
    n_partner: u32,     // the partner's points
}


@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> state: State;
@group(0) @binding(2) var<storage, read> starts: array<u32>;
@group(0) @binding(3) var<storage, read> sorted: array<vec4<u32>>;
@group(0) @binding(4) var<uniform> search: Search;
@group(0) @binding(5) var<storage, read> probes: array<vec4<f32>>;
@group(0) @binding(6) var<storage, read> partner: array<vec4<f32>>;
@group(0) @binding(7) var<storage, read> topology: array<u32>;
@group(0) @binding(8) var<storage, read_write> hits: array<SurfaceHit>;
// [0]: the squared longest edge of the partner's surface at this step (f32 bits), by
// `longest_edge`; [1]: 1 once a step's binning left a point out (the partner grew past the grid,
// or a point is not finite), kept for the host's next look.
@group(0) @binding(9) var<storage, read_write> edge: array<atomic<u32>, 4>;

const NONE: u32 = 0xffffffffu;
// Where on a triangle its nearest point lies: the face, an edge (from corner e to e + 1), a corner.
const FACE: u32 = 0u;
const EDGE: u32 = 1u;
const CORNER: u32 = 4u;

fn corner_of(t: u32, c: u32) -> u32 {
    return topology[search.tri_at + 3u * t + c];
}

fn point(i: u32) -> vec3<f32> {
    return partner[i].xyz;
}

// glam's `normalize_or_zero`: times the reciprocal of the length, or zero where that is not a
// positive finite number.
fn normalize_or_zero(v: vec3<f32>) -> vec3<f32> {
    let rcp = 1.0 / sqrt(dot3(v, v));
    if is_finite_f32(rcp) && rcp > 0.0 {
        return v * rcp;
    }
    return vec3<f32>(0.0);
}

// The unit normal of triangle `t` (zero for a degenerate one): `face_normal`.
fn face_normal(t: u32) -> vec3<f32> {
    let a = point(corner_of(t, 0u));
    return normalize_or_zero(cross3(point(corner_of(t, 1u)) - a, point(corner_of(t, 2u)) - a));
}

// glam's `acos_approx` (DirectXMath's `XMScalarAcos`), the angle `angle_between` takes.
fn acos_approx(v: f32) -> f32 {
    let nonnegative = v >= 0.0;
    let x = abs(v);
    var omx = 1.0 - x;
    if omx < 0.0 {
        omx = 0.0;
    }
    let root = sqrt(omx);
    var result = ((((((-0.0012624911 * x + 0.00667009) * x - 0.017088126) * x + 0.03089188) * x
        - 0.050174303) * x + 0.08897899) * x - 0.2145988) * x + 1.5707963;
    result = result * root;
    if nonnegative {
        return result;
    }
    return 3.14159265358979323846264338327950288 - result;
}

fn angle_between(u: vec3<f32>, w: vec3<f32>) -> f32 {
    return acos_approx(dot3(u, w) / sqrt(dot3(u, u) * dot3(w, w)));
}

// The angle-weighted normal at partner point `v`, over its triangles in order: `vertex_normal`.
fn vertex_normal(v: u32) -> vec3<f32> {
    var n = vec3<f32>(0.0);
    let o = point(v);
    for (var a = topology[search.off_at + v]; a < topology[search.off_at + v + 1u]; a++) {
        let t = topology[search.adj_at + a];
        // (Its first corner that is v.)
        var c = 0u;
        if corner_of(t, 0u) != v && corner_of(t, 1u) == v {
            c = 1u;
        } else if corner_of(t, 0u) != v && corner_of(t, 2u) == v {
            c = 2u;
        }
        let u = point(corner_of(t, (c + 1u) % 3u)) - o;
        let w = point(corner_of(t, (c + 2u) % 3u)) - o;
        n = n + face_normal(t) * angle_between(u, w);
    }
    return n;
}

fn ratio(n: f32, d: f32) -> f32 {
    if d > 0.0 {
        return n / d;
    }
    return 0.0;
}

// The nearest point of triangle abc to p (`closest_region` then `closest_on_triangle`, Ericson
// §5.1.5): xyz its barycentric weights, w the feature (FACE, EDGE + e, CORNER + c) as bits;
// w = NONE for a degenerate face (its neighbours cover its edges).
fn closest_on_triangle(p: vec3<f32>, a: vec3<f32>, b: vec3<f32>, c: vec3<f32>) -> vec4<f32> {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = dot3(ab, ap);
    let d2 = dot3(ac, ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return vec4<f32>(1.0, 0.0, 0.0, bitcast<f32>(CORNER));
    }
    let bp = p - b;
    let d3 = dot3(ab, bp);
    let d4 = dot3(ac, bp);
    if d3 >= 0.0 && d4 <= d3 {
        return vec4<f32>(0.0, 1.0, 0.0, bitcast<f32>(CORNER + 1u));
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = ratio(d1, d1 - d3);
        return vec4<f32>(1.0 - v, v, 0.0, bitcast<f32>(EDGE));
    }
    let cp = p - c;
    let d5 = dot3(ab, cp);
    let d6 = dot3(ac, cp);
    if d6 >= 0.0 && d5 <= d6 {
        return vec4<f32>(0.0, 0.0, 1.0, bitcast<f32>(CORNER + 2u));
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = ratio(d2, d2 - d6);
        return vec4<f32>(1.0 - w, 0.0, w, bitcast<f32>(EDGE + 2u));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
        let w = ratio(d4 - d3, (d4 - d3) + (d5 - d6));
        return vec4<f32>(0.0, 1.0 - w, w, bitcast<f32>(EDGE + 1u));
    }
    let sum = va + vb + vc;
    if !(sum > 0.0) || !is_finite_f32(sum) {
        return vec4<f32>(0.0, 0.0, 0.0, bitcast<f32>(NONE));
    }
    let v = vb / sum;
    let w = vc / sum;
    return vec4<f32>(1.0 - v - w, v, w, bitcast<f32>(FACE));
}

// The largest of |x|, |y|, |z|.
fn max_abs3(v: vec3<f32>) -> f32 {
    return max(max(abs(v.x), abs(v.y)), abs(v.z));
}

// One probe's search, as it goes (per invocation): where it is, the nearest triangle so far
// and what bounds the others.
var<private> probe_p: vec3<f32>;
var<private> probe_entry: vec3<f32>;
var<private> near2: f32;
var<private> found: bool;
var<private> best_d2: f32;
var<private> best_t: u32;
var<private> best: vec4<f32>;
// The squared distance within which a triangle may still be nearer.
var<private> bound: f32;
// A lower bound of the squared distance to every triangle passed over or measured.
var<private> lower: f32;
// How near, squared, a point must be for its triangles to be looked at: `near2` until one is
// found, then its distance plus the longest edge (every point of a triangle lies within its
// longest edge of each corner), a little more for rounding.
var<private> corners2: f32;
var<private> longest: f32;
// The nearest point beyond `near`, squared, if any.
var<private> beyond: f32;
var<private> any_beyond: bool;

// Triangle t at d2, its nearest point `near` (weights and feature): the nearest so far where it
// is within the bound and nearer (ties to the smaller index).
fn offer(t: u32, d2: f32, near: vec4<f32>) {
    if d2 <= bound && (!found || d2 < best_d2 || (d2 == best_d2 && t < best_t)) {
        found = true;
        best_d2 = d2;
        best_t = t;
        best = near;
        bound = d2;
        let r = (sqrt(d2) + longest) * 1.001;
        corners2 = min(r * r, near2);
    }
}

// Triangle t, its corners c0, c1, c2, measured from the probe and offered as the nearest: what
// it adds to the lower bound (its box's squared distance where it is passed over, else its
// own), or -1 where it adds nothing (a corner not finite, a degenerate face).
fn measure(t: u32, c0: vec3<f32>, c1: vec3<f32>, c2: vec3<f32>) -> f32 {
    let p = probe_p;
    // (A triangle with a corner not finite is never one: the CPU's lists leave it out.)
    if !(is_finite3(c0) && is_finite3(c1) && is_finite3(c2)) {
        return -1.0;
    }
    let box_lo = min(min(c0, c1), c2);
    let box_hi = max(max(c0, c1), c2);
    let out = max(max(box_lo - p, p - box_hi), vec3<f32>(0.0));
    let box_d2 = dot3(out, out);
    // Farther than the cutoff, or than the nearest so far; or facing away from the way it came
    // in: the far side (still a bound).
    if box_d2 > bound || (any(probe_entry != vec3<f32>(0.0)) && dot3(face_normal(t), probe_entry) < 0.0) {
        return box_d2;
    }
    let near = closest_on_triangle(p, c0, c1, c2);
    if bitcast<u32>(near.w) == NONE {
        return -1.0;
    }
    let d2 = dist2(p, near.x * c0 + near.y * c1 + near.z * c2);
    offer(t, d2, near);
    return d2;
}

// Triangle t measured before the walk (the last step's nearest), as the walk would: only what it
// finds, no bound (the walk meets it again where it counts).
fn try_first(t: u32) {
    _ = measure(t, point(corner_of(t, 0u)), point(corner_of(t, 1u)), point(corner_of(t, 2u)));
}

// The triangles at partner point i (within `near`), each at its first corner that near.
fn triangles_at(i: u32) {
    let p = probe_p;
    for (var a = topology[search.off_at + i]; a < topology[search.off_at + i + 1u]; a++) {
        let t = topology[search.adj_at + a];
        let c0 = point(corner_of(t, 0u));
        let c1 = point(corner_of(t, 1u));
        let c2 = point(corner_of(t, 2u));
        // Each triangle once: at its first corner that near (in the block).
        var first = corner_of(t, 2u);
        if dist2(c0, p) <= near2 {
            first = corner_of(t, 0u);
        } else if dist2(c1, p) <= near2 {
            first = corner_of(t, 1u);
        }
        if first != i {
            continue;
        }
        let bounded = measure(t, c0, c1, c2);
        if bounded >= 0.0 {
            lower = min(lower, bounded);
        }
    }
}

// The points binned in voxel q (a hashed slot holds other voxels' points too, passed over).
fn walk(q: vec3<u32>, origin: vec3<f32>) {
    let s = slot_of(q);
    for (var e = starts[s]; e < starts[s + 1u]; e++) {
        let i = sorted[e].w;
        let pi = point(i);
        if any(voxel_of(pi, origin).xyz != q) {
            continue;
        }
        let di2 = dist2(pi, probe_p);
        if di2 > near2 {
            // A point farther than `near` is no corner of a triangle within the cutoff; its
            // distance less the longest edge bounds the triangles at it (taken once, after the
            // walk: the bound grows with the distance, so the nearest gives the least).
            if !any_beyond || di2 < beyond {
                beyond = di2;
            }
            any_beyond = true;
        } else if di2 <= corners2 {
            triangles_at(i);
        }
    }
}

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let k = item_index(gid, nwg);
    if k == 0u && atomicLoad(&state.binned) < search.n_partner {
        atomicStore(&edge[1], 1u);
    }
    if k >= search.n_probes {
        return;
    }
    let p = probes[k].xyz;
    let entry = hits[k].entry.xyz;
    // The last step's nearest (NONE: none, or not searched), tried first.
    let last = hits[k].triangle;
    // Farther from any push than the bodies have moved since it was measured: not searched.
    if hits[k].clear > 0.0 {
        var skipped = SurfaceHit();
        skipped.entry = hits[k].entry;
        skipped.triangle = NONE;
        skipped.clear = hits[k].clear;
        hits[k] = skipped;
        return;
    }
    let origin = state.origin.xyz;
    probe_p = p;
    probe_entry = entry;
    found = false;
    best_d2 = 0.0;
    best_t = NONE;
    best = vec4<f32>(0.0);
    bound = search.cutoff * search.cutoff;
    any_beyond = false;
    beyond = 0.0;
    // The longest edge now: a triangle within the cutoff has a corner within `near`, and every
    // point that near is binned within `reach` voxels of the probe's own, each way.
    longest = sqrt(bitcast<f32>(atomicLoad(&edge[0])));
    let near = search.cutoff + longest;
    near2 = near * near;
    corners2 = near2;
    // (At most the grid across: a surface stretched past all sense is walked whole.)
    let across = f32(max(max(params.dims.x, params.dims.y), params.dims.z));
    let reach = i32(clamp(ceil(near / search.voxel), 1.0, across));
    // A lower bound of the distance to every triangle (`Side::hits`' `lower`): those passed over
    // or measured, those with a corner in the block but none near (that corner's distance less
    // the longest edge), and those with no corner in the block (`reach` voxels less that).
    let far = max(f32(reach) * search.voxel - longest, 0.0);
    lower = far * far;
    // The probe's voxel, as `voxel_of` counts them, or where it would be past the grid's faces
    // (kept within a block of them): a probe just outside the grid walks the part of its block
    // inside it, since the points binned near a face may be near it. One whose block misses
    // the grid is searched again at the next step.
    let v = voxel_of(p, origin);
    let dims = vec3<i32>(params.dims.xyz);
    var at = vec3<i32>(0);
    var searched = false;
    if is_finite3(p) {
        let g = clamp(
            floor((p - origin) * params.inv),
            vec3<f32>(-1.0 - f32(reach)),
            vec3<f32>(params.dims.xyz) + f32(reach)
        );
        at = vec3<i32>(g);
        searched = all(at - vec3<i32>(reach) < dims) && all(at + vec3<i32>(reach) >= vec3<i32>(0));
    }
    if searched {
        // The last step's nearest first, so that most triangles are passed over (the answer
        // is the same without it: the nearest, ties to the smaller index).
        if last < search.n_triangles {
            try_first(last);
        }
        // The probe's own voxel first, then the others that the sphere of `near` about it
        // reaches: only their points can be corners of a candidate, and once one is found,
        // only those within its distance plus the longest edge. The other voxels' points only
        // bound the distance (`beyond`), which only counts where nothing is found; and a voxel
        // whose box lies farther than what is bounded by then is passed over (no point in it
        // could lower the bound: the same bound as walking it, sooner). A box's distance is
        // shaved by a thousandth of a voxel, and by a millionth of the coordinates' size (some
        // fifteen times their rounding, far from the origin), so that rounding never passes over
        // a point that counts.
        let size = max(max_abs3(p), max_abs3(origin));
        let shave = 1e-3 * search.voxel + 1e-6 * size;
        if v.w == 1u {
            walk(v.xyz, origin);
        }
        var later: array<vec4<f32>, 27>;
        var n_later = 0u;
        let lo = at - vec3<i32>(reach);
        let side = 2 * reach + 1;
        for (var z = 0; z < side; z++) {
            for (var y = 0; y < side; y++) {
                for (var x = 0; x < side; x++) {
                    let q = lo + vec3<i32>(x, y, z);
                    if any(q < vec3<i32>(0)) || any(q >= dims) || (v.w == 1u && all(vec3<u32>(q) == v.xyz)) {
                        continue;
                    }
                    let box_lo = origin + vec3<f32>(q) * search.voxel;
                    let out = max(max(box_lo - p, p - (box_lo + vec3<f32>(search.voxel))), vec3<f32>(0.0));
                    let d = sqrt(dot3(out, out)) - shave;
                    if d > near && n_later < 27u {
                        later[n_later] = vec4<f32>(vec3<f32>(q), d);
                        n_later++;
                    } else if !found || d <= 0.0 || d * d <= corners2 {
                        walk(vec3<u32>(q), origin);
                    }
                }
            }
        }
        for (var l = 0u; l < n_later; l++) {
            if found {
                break;
            }
            var lowest = lower;
            if any_beyond {
                let bounded = max(sqrt(beyond) - longest, 0.0);
                lowest = min(lowest, bounded * bounded);
            }
            let could = max(later[l].w - longest, 0.0);
            if could * could <= lowest {
                walk(vec3<u32>(later[l].xyz), origin);
            }
        }
        if any_beyond {
            let d = max(sqrt(beyond) - longest, 0.0);
            lower = min(lower, d * d);
        }
    }
    var hit = SurfaceHit();
    hit.entry = hits[k].entry;
    hit.triangle = best_t;
    // (Clearances are shaved by a thousandth, so that rounding never skips a push.)
    if !found && searched {
        hit.clear = (sqrt(lower) - search.cutoff) * 0.999;
    }
    if found {
        // The push (`Side::hit`): the sign from the nearest feature's pseudo-normal.
        let t = best_t;
        let feature = bitcast<u32>(best.w);
        var pseudo = vec3<f32>(0.0);
        if feature == FACE {
            pseudo = face_normal(t);
        } else if feature < CORNER {
            let other = topology[search.nbr_at + 3u * t + (feature - EDGE)];
            pseudo = face_normal(t);
            if other != NONE {
                pseudo = pseudo + face_normal(other);
            }
        } else {
            pseudo = vertex_normal(corner_of(t, feature - CORNER));
        }
        let qn = best.x * point(corner_of(t, 0u)) + best.y * point(corner_of(t, 1u)) + best.z * point(corner_of(t, 2u));
        let d = p - qn;
        let dist = sqrt(best_d2);
        let outside = dot3(d, pseudo) >= 0.0;
        let s = select(-dist, dist, outside);
        hit.weights = vec4<f32>(best.xyz, s);
        if !(s >= search.gap + search.margin || -s > search.reach) {
            var normal = normalize_or_zero(pseudo);
            if dist > 1e-6 * search.reach {
                normal = select(-d / dist, d / dist, outside);
            }
            if any(normal != vec3<f32>(0.0)) {
                hit.normal = vec4<f32>(normal, search.gap - s);
                hit.found = 1u;
            }
        }
        // Outside beyond the gap (and the margin): no push until it comes within it.
        let near_gm = search.gap + search.margin;
        if hit.found == 0u && s >= near_gm {
            hit.clear = (s - near_gm) * 0.999;
        }
    }
    hits[k] = hit;
}

// The surface's longest edge now, squared, into `edge[0]` (cleared before): each triangle's
// three edges. (One not finite is passed over: its triangle is never a candidate.)
@compute @workgroup_size(WORKGROUP_SIZE)
fn longest_edge(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let t = item_index(gid, nwg);
    if t >= search.n_triangles {
        return;
    }
    let a = point(corner_of(t, 0u));
    let b = point(corner_of(t, 1u));
    let c = point(corner_of(t, 2u));
    let e2 = max(max(dist2(b, a), dist2(c, b)), dist2(a, c));
    if is_finite_f32(e2) {
        atomicMax(&edge[0], bitcast<u32>(e2));
    }
}
