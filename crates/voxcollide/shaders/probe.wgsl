// Pass 3: each B vertex finds its voxel (or the 3×3×3 block), walks the sorted A vertices of
// its voxels, picks its partner(s) by (d2, index), writes its own force (w = 1 when it collides)
// and adds the fixed-point shares of the opposite force to A's 64-bit accumulators. CPU twins:
// VoxelDetector::detect and the eliminators.

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> state: State;
// B in A's slot order (passes bin_b to sort_b): (position bits, index in B); or, where
// SORTED_B is false, B's own positions as given (their bits; the index is the invocation's).
@group(0) @binding(2) var<storage, read> sorted_b: array<vec4<u32>>;
@group(0) @binding(3) var<storage, read> start: array<u32>;
// A in slot order: (position bits, index in A). A walk reads positions here, and A's force
// accumulators are kept in this order too, so that no access follows A's own order.
@group(0) @binding(4) var<storage, read> sorted: array<vec4<u32>>;
// Per sorted A vertex 8 words: the low words of the x, y, z totals, one unused, then the high
// words.
@group(0) @binding(5) var<storage, read_write> fixed: array<atomic<u32>>;
@group(0) @binding(6) var<storage, read_write> force_b: array<vec4<f32>>;

var<workgroup> wg_colliding: atomic<u32>;

// The search and direction, fixed when the pipeline is made (they equal params.search and
// params.direction), so that the compiler drops the paths a backend never takes: a software
// adapter such as llvmpipe otherwise runs every branch under a mask (docs/performance-notes.md).
override SEARCH: u32 = SEARCH_VOXEL;
override DIRECTION: u32 = DIRECTION_PAIRWISE;
// Equals params.dense != 0u: with a slot per voxel, no slot holds another voxel's vertices.
override DENSE: bool = false;
// False: B is probed in the order it comes in, its sort skipped (GpuCollision::set_sort_b).
override SORTED_B: bool = true;

// The nearest candidates so far, in (d2, index) order; only the first `n` are valid. `at`:
// where each sits in `sorted` (its position there, and its force accumulator).
struct Nearest {
    d: vec3<f32>,
    i: vec3<u32>,
    at: vec3<u32>,
    n: u32,
}

fn before(da: f32, ia: u32, db: f32, ib: u32) -> bool {
    return da < db || (da == db && ia < ib);
}

// Straight-line on purpose: Mesa's llvmpipe caps the iterations of all loops nested in one
// outermost loop at 65535, so the walk below keeps to one loop iteration per list entry.
fn insert(t: ptr<function, Nearest>, d: f32, i: u32, at: u32) {
    let n = (*t).n;
    // k = how many kept entries come before (d, i); they are sorted.
    let k = select(0u, 1u, n > 0u && before((*t).d.x, (*t).i.x, d, i))
        + select(0u, 1u, n > 1u && before((*t).d.y, (*t).i.y, d, i))
        + select(0u, 1u, n > 2u && before((*t).d.z, (*t).i.z, d, i));
    if k == 0u {
        (*t).d = vec3<f32>(d, (*t).d.x, (*t).d.y);
        (*t).i = vec3<u32>(i, (*t).i.x, (*t).i.y);
        (*t).at = vec3<u32>(at, (*t).at.x, (*t).at.y);
    } else if k == 1u {
        (*t).d = vec3<f32>((*t).d.x, d, (*t).d.y);
        (*t).i = vec3<u32>((*t).i.x, i, (*t).i.y);
        (*t).at = vec3<u32>((*t).at.x, at, (*t).at.y);
    } else if k == 2u {
        (*t).d.z = d;
        (*t).i.z = i;
        (*t).at.z = at;
    } else {
        return;
    }
    (*t).n = min(n + 1u, 3u);
}

// Adds count `c` to the 64-bit accumulator of vertex `i`, `axis`. It holds the total T biased
// by 2^31, S = T + 2^31 = high * 2^32 + low, so that a total within i32 never carries into the
// high word (one atomic per count, not two); the low word is stored as low ^ 2^31 (= T's own low
// word), so that zeroed memory is T = 0. The sum is exact and independent of order: the carries
// out of the low word add up to the same total whatever the order.
fn add_fixed(at: u32, axis: u32, c: i32) {
    if c == 0 {
        return;
    }
    let u = bitcast<u32>(c);
    let old = atomicAdd(&fixed[8u * at + axis], u) ^ 0x80000000u;
    let carry = select(0u, 1u, old + u < old);
    let delta = carry + select(0u, 0xffffffffu, c < 0);
    if delta != 0u {
        atomicAdd(&fixed[8u * at + 4u + axis], delta);
    }
}

fn add_force_a(at: u32, f: vec3<f32>) {
    add_fixed(at, 0u, i32(round(f.x * params.scale)));
    add_fixed(at, 1u, i32(round(f.y * params.scale)));
    add_fixed(at, 2u, i32(round(f.z * params.scale)));
}

// stiffness * depth, the depth clamped to [0, max_depth] (NaN counts as 0). CPU twin:
// Penalty::of_depth in src/eliminate.rs, with the same comparisons.
fn penalty_of_depth(depth: f32) -> f32 {
    let d0 = select(0.0, depth, depth > 0.0);
    let d = select(params.max_depth, d0, d0 < params.max_depth);
    return params.stiffness * d;
}

// The magnitude of the force on b along the plane normal n of a0, a1, a2 (ForceLaw::plane).
fn plane_magnitude(b: vec3<f32>, a0: vec3<f32>, a1: vec3<f32>, a2: vec3<f32>, n: vec3<f32>) -> f32 {
    if params.response == RESPONSE_CONSTANT {
        return params.magnitude;
    }
    let centroid = (a0 + a1 + a2) / 3.0;
    return penalty_of_depth(params.gap - dot3(b - centroid, n));
}

// The magnitude of the force on b at squared distance d2 from its partner (ForceLaw::pairwise).
fn pairwise_magnitude(d2: f32) -> f32 {
    if params.response == RESPONSE_CONSTANT {
        return params.magnitude;
    }
    return penalty_of_depth(params.gap_reach - sqrt(d2));
}

// (b - a) / sqrt(d2), or for coincident vertices the unit vector from the center, or +z.
fn pairwise_direction(center: vec3<f32>, a: vec3<f32>, b: vec3<f32>) -> vec3<f32> {
    let d2 = dist2(b, a);
    if d2 >= DEGENERATE {
        return (b - a) / sqrt(d2);
    }
    let e2 = dist2(b, center);
    if e2 >= DEGENERATE {
        return (b - center) / sqrt(e2);
    }
    return vec3<f32>(0.0, 0.0, 1.0);
}

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    // Invocation k probes the k-th B vertex in A's slot order, so that neighbouring invocations
    // walk neighbouring slots whatever order B comes in; B's vertices outside the grid are not
    // sorted, and their forces stay cleared.
    let k = item_index(gid, nwg);
    var hit = false;
    if SORTED_B {
        if k < atomicLoad(&state.binned_b) {
            let entry = sorted_b[k];
            hit = probe(entry.w, bitcast<vec3<f32>>(entry.xyz));
        }
    } else if k < params.n_b {
        // (A vertex outside the grid gets a cleared force, as the sort would leave it.)
        hit = probe(k, bitcast<vec3<f32>>(sorted_b[k].xyz));
    }
    if hit {
        atomicAdd(&wg_colliding, 1u);
    }
    workgroupBarrier();
    if lid == 0u {
        let n = atomicLoad(&wg_colliding);
        if n != 0u {
            atomicAdd(&state.colliding, n);
        }
    }
}

// Walks the vertices of voxel `v` (one slot's range; hashed, other voxels' vertices in the slot
// are skipped), keeping the nearest by (d2, index) as `best`'s first entry. False when a driver's
// loop cap cut the walk short.
fn walk_own_voxel(p: vec3<f32>, v: vec3<u32>, best: ptr<function, Nearest>) -> bool {
    let s = slot_in(v, DENSE);
    var k = start[s];
    let end = start[s + 1u];
    let origin_v = state.origin.xyz;
    let inv = params.inv;
    let vf = vec3<f32>(v);
    loop {
        if k >= end {
            return true;
        }
        let entry = sorted[k];
        let at = k;
        k++;
        let a = bitcast<vec3<f32>>(entry.xyz);
        if !DENSE && any(floor((a - origin_v) * inv) != vf) {
            continue;
        }
        let d2 = dist2(p, a);
        if (*best).n == 0u || before(d2, entry.w, (*best).d.x, (*best).i.x) {
            (*best).d.x = d2;
            (*best).i.x = entry.w;
            (*best).at.x = at;
            (*best).n = 1u;
        }
    }
    return false;
}

fn probe(j: u32, p: vec3<f32>) -> bool {
    let origin = state.origin.xyz;
    let center = state.center.xyz;
    let vb = voxel_of(p, origin);
    if vb.w == 0u {
        force_b[j] = vec4<f32>(0.0);
        return false;
    }
    let voxel_only = SEARCH == SEARCH_VOXEL;
    let plane = DIRECTION == DIRECTION_PLANE_NORMAL;
    // Voxel search: partner candidates in b's voxel (`own`), plane candidates in the block.
    // Neighbours: one candidate set, the block within the radius, for both.
    var own = Nearest();
    var block = Nearest();
    var lo = vb.xyz;
    var hi = vb.xyz;
    if !voxel_only || plane {
        lo = max(vb.xyz, vec3<u32>(1u)) - vec3<u32>(1u);
        hi = min(vb.xyz + vec3<u32>(1u), params.dims.xyz - vec3<u32>(1u));
    }
    var done = false;
    if voxel_only && !plane {
        // The paper's rule with a pairwise partner: b's own voxel, one range, the best (d2, index).
        done = walk_own_voxel(p, vb.xyz, &block);
    } else {
        // A block row's voxels (x = lo.x ..= hi.x) are consecutive slots, so their vertices are one
        // range of the sorted array (hashed: a row whose slots wrap past the last one is two). The
        // ranges are read first, so that the walk's loop reads nothing but vertices: llvmpipe runs
        // every load in a loop body on every iteration, masked, even in a branch no lane takes.
        let ext = hi - lo + vec3<u32>(1u);
        let rows = ext.y * ext.z;
        let slots = params.slot_mask + 1u;
        // Loop-invariant values in locals: llvmpipe reloads a uniform inside a loop, lane by lane.
        let origin_v = state.origin.xyz;
        let inv = params.inv;
        let r2 = params.r2;
        var range_start: array<u32, 18>;
        var range_end: array<u32, 18>;
        var range_y: array<u32, 18>;
        var range_z: array<u32, 18>;
        var ranges = 0u;
        // Under the neighbour search a row (or one end voxel of it) that the sphere of the radius
        // around p cannot reach is left out. Generous for the f32 rounding of positions, faces and
        // d2 (as ParallelCpuCollision): a few ulps of the largest magnitude and 1e-3 of the radius.
        let neighbours = SEARCH == SEARCH_NEIGHBOURS;
        let vs = 1.0 / inv;
        let radius = sqrt(r2);
        let margins = 1e-3 * radius
            + 16.0 * 1.1920929e-7 * (abs(p) + abs(origin_v) + vs * vec3<f32>(params.dims.xyz));
        let margin = max(margins.x, max(margins.y, margins.z));
        let reach2 = (radius + margin) * (radius + margin);
        // How far p is from the faces of its voxel below and above, along x.
        let below_x = p.x - (origin_v.x + f32(vb.x) * vs);
        let above_x = (origin_v.x + f32(vb.x + 1u) * vs) - p.x;
        // No division anywhere in the walk: a vector integer division is eight scalar ones on a
        // CPU adapter.
        var y = lo.y;
        var z = lo.z;
        for (var r = 0u; r < rows; r++) {
            var x0 = lo.x;
            var x1 = hi.x;
            var reached = true;
            if neighbours {
                // The distances from p to the row's slab in y and in z, less the margin.
                let below = vec2<f32>(origin_v.y + f32(y) * vs, origin_v.z + f32(z) * vs);
                let above = vec2<f32>(origin_v.y + f32(y + 1u) * vs, origin_v.z + f32(z + 1u) * vs);
                let g = max(max(p.yz - above, below - p.yz) - margin, vec2<f32>(0.0));
                let gy = g.x;
                let gz = g.y;
                let rest = reach2 - gy * gy - gz * gz;
                reached = rest >= 0.0;
                let half = sqrt(max(rest, 0.0)) + margin;
                x0 = select(x0, vb.x, below_x > half);
                x1 = select(x1, vb.x, above_x > half);
            }
            let len = x1 - x0 + 1u;
            // The row's first slot; dense rows never run past the table's end, hashed ones may.
            let first = slot_in(vec3<u32>(x0, y, z), DENSE);
            let k1 = start[min(first + len, slots)];
            let k0 = start[first];
            if reached && k1 > k0 {
                range_start[ranges] = k0;
                range_end[ranges] = k1;
                range_y[ranges] = y;
                range_z[ranges] = z;
                ranges++;
            }
            if !DENSE && first + len > slots {
                // The wrapped part: slots 0 .. first + len - slots (start[0] is 0).
                let k2 = start[first + len - slots];
                if reached && k2 > 0u {
                    range_start[ranges] = 0u;
                    range_end[ranges] = k2;
                    range_y[ranges] = y;
                    range_z[ranges] = z;
                    ranges++;
                }
            }
            y++;
            if y > hi.y {
                y = lo.y;
                z++;
            }
        }
        // One loop over the ranges' vertices, one iteration each, so that a driver's loop cap
        // (llvmpipe: 65535) is reached as late as possible and, if it is reached, seen: the loop
        // then ends before the last range is done.
        var next_range = 0u;
        var k = 0u;
        var end = 0u;
        loop {
            if k >= end {
                if next_range >= ranges {
                    done = true;
                    break;
                }
                k = range_start[next_range];
                end = range_end[next_range];
                y = range_y[next_range];
                z = range_z[next_range];
                next_range++;
            }
            let entry = sorted[k];
            let at = k;
            k++;
            let a = bitcast<vec3<f32>>(entry.xyz);
            let i = entry.w;
            // The voxel is computed as the bin pass computed it, so it is the same one.
            let q = floor((a - origin_v) * inv);
            // Hashed: only vertices whose own voxel is in this row belong to it (aliasing).
            if !DENSE && (q.y != f32(y) || q.z != f32(z) || q.x < f32(lo.x) || q.x > f32(hi.x)) {
                continue;
            }
            let d2 = dist2(p, a);
            if !plane {
                // The neighbour search with a pairwise partner (the voxel search's is walked by
                // walk_own_voxel): keep the best (d2, index) within the radius as block's first.
                if d2 < r2 && (block.n == 0u || before(d2, i, block.d.x, block.i.x)) {
                    block.d.x = d2;
                    block.i.x = i;
                    block.at.x = at;
                    block.n = 1u;
                }
            } else if voxel_only {
                if all(vec3<f32>(q.x, f32(y), f32(z)) == vec3<f32>(vb.xyz)) {
                    insert(&own, d2, i, at);
                }
                insert(&block, d2, i, at);
            } else if d2 < r2 {
                insert(&block, d2, i, at);
            }
        }
    }
    if !done {
        atomicMax(&state.truncated, ~j);
    }
    var partner = block;
    if voxel_only && plane {
        partner = own;
    }
    if partner.n == 0u {
        force_b[j] = vec4<f32>(0.0);
        return false;
    }
    if plane && block.n == 3u {
        let a0 = bitcast<vec3<f32>>(sorted[block.at[0]].xyz);
        let a1 = bitcast<vec3<f32>>(sorted[block.at[1]].xyz);
        let a2 = bitcast<vec3<f32>>(sorted[block.at[2]].xyz);
        let c = cross3(a1 - a0, a2 - a0);
        let len = sqrt(dot3(c, c));
        if len >= DEGENERATE {
            var n = c / len;
            let centroid = (a0 + a1 + a2) / 3.0;
            if dot3(n, centroid - center) < 0.0 {
                n = -n;
            }
            let f_b = plane_magnitude(p, a0, a1, a2, n) * n;
            force_b[j] = vec4<f32>(f_b, 1.0);
            let share = -f_b / 3.0;
            add_force_a(block.at[0], share);
            add_force_a(block.at[1], share);
            add_force_a(block.at[2], share);
            return true;
        }
    }
    let at = partner.at[0];
    let pa = bitcast<vec3<f32>>(sorted[at].xyz);
    let f_b = pairwise_magnitude(dist2(p, pa)) * pairwise_direction(center, pa, p);
    force_b[j] = vec4<f32>(f_b, 1.0);
    add_force_a(at, -f_b);
    return true;
}
