// The Neo-Hookean tetrahedra of a body (docs/design.md §12, `model = "neo-hookean"`), written in the same
// order as their CPU twin (src/fem.rs), each product rounded as the CPU rounds it (`unfused`), so
// that the explicit step's forces equal the CPU's to the bit: each tetrahedron's force on a corner, and the implicit
// integrator's projected stiffness (`Tangent`) with its product. A shader that composes this file
// declares `pos`, `tet_index` and `tet_rest`:
//
// - `tet_index: array<u32>`: the corners of every tetrahedron (4 each), then per vertex the
//   offsets of its (tetrahedron, corner) pairs (`sim.n + 1`), then the pairs, each `4·k + c`;
// - `tet_rest: array<vec4<f32>>`: per tetrahedron the columns of `D_m⁻¹` (3 each), its weight
//   (its rest volume times its modulus over the material's, CPU: `Elements::weight`) in the
//   first column's `w`.
//
// The material is `sim.mu`, `sim.lambda` (`λ' = λ + μ`) and `sim.alpha`; `sim.tets` counts them
// (0: a body of springs).

fn tet_corners(k: u32) -> vec4<u32> {
    let b = 4u * k;
    return vec4<u32>(tet_index[b], tet_index[b + 1u], tet_index[b + 2u], tet_index[b + 3u]);
}

fn tet_dm_inv(k: u32) -> mat3x3<f32> {
    return mat3x3<f32>(tet_rest[3u * k].xyz, tet_rest[3u * k + 1u].xyz, tet_rest[3u * k + 2u].xyz);
}

// Its rest volume times its modulus over the material's: what its energy is scaled by.
fn tet_weight(k: u32) -> f32 {
    return tet_rest[3u * k].w;
}

// Vertex i's (tetrahedron, corner) pairs: `tet_index[range.x..range.y]`, each `4·k + c`.
fn tet_range(i: u32) -> vec2<u32> {
    let base = 4u * sim.tets;
    return vec2<u32>(tet_index[base + i], tet_index[base + i + 1u]) + vec2<u32>(base + sim.n + 1u);
}

// A product, kept from being fused into the sum it feeds. A fused multiply-add rounds once where
// the CPU rounds twice, and llvmpipe fuses these matrix expressions (measured: a tetrahedron's
// `V₀·D_s`, gathered, differed from the CPU's in the last bit; `D_s` alone did not). A select on
// a condition the compiler cannot know (no body has 2³² − 1 tetrahedra) stands between them.
fn unfused3(v: vec3<f32>) -> vec3<f32> {
    return select(v, vec3<f32>(0.0), sim.tets == 0xffffffffu);
}

fn unfused(x: f32) -> f32 {
    return select(x, 0.0, sim.tets == 0xffffffffu);
}

// glam's `Vec3::dot`, each product rounded.
fn dot_unfused(u: vec3<f32>, v: vec3<f32>) -> f32 {
    return unfused(u.x * v.x) + unfused(u.y * v.y) + unfused(u.z * v.z);
}

// glam's `Vec3::cross`, each product rounded.
fn cross_unfused(u: vec3<f32>, v: vec3<f32>) -> vec3<f32> {
    return unfused3(vec3<f32>(u.y * v.z, u.z * v.x, u.x * v.y))
        - unfused3(vec3<f32>(u.z * v.y, u.x * v.z, u.y * v.x));
}

// glam's `Mat3 * Vec3`: `x_axis·v.x + y_axis·v.y + z_axis·v.z`, in that order, each product
// rounded.
fn mv3(m: mat3x3<f32>, v: vec3<f32>) -> vec3<f32> {
    return unfused3(m[0] * v.x) + unfused3(m[1] * v.y) + unfused3(m[2] * v.z);
}

// glam's `Mat3 * Mat3`, column by column.
fn mm3(a: mat3x3<f32>, b: mat3x3<f32>) -> mat3x3<f32> {
    return mat3x3<f32>(mv3(a, b[0]), mv3(a, b[1]), mv3(a, b[2]));
}

// glam's `Mat3::determinant`: `x·(y × z)`.
fn det3(m: mat3x3<f32>) -> f32 {
    return dot_unfused(m[0], cross_unfused(m[1], m[2]));
}

// `F` of tetrahedron k with its corners at `p`.
fn deformation(k: u32, p0: vec3<f32>, p1: vec3<f32>, p2: vec3<f32>, p3: vec3<f32>) -> mat3x3<f32> {
    return mm3(mat3x3<f32>(p1 - p0, p2 - p0, p3 - p0), tet_dm_inv(k));
}

// Corner `c`'s column of a tetrahedron's `V₀·P·D_m⁻ᵀ`-shaped `h`, or minus their sum for corner 0
// (CPU: `fem::corner_of`).
fn corner_of(h: mat3x3<f32>, c: u32) -> vec3<f32> {
    if c == 0u {
        return -(h[0] + h[1] + h[2]);
    }
    return h[c - 1u];
}

// The force of tetrahedron k on its corner c (CPU: `Elements::corner_force`).
fn tet_corner_force(k: u32, c: u32) -> vec3<f32> {
    let t = tet_corners(k);
    let f = deformation(k, pos[t.x].xyz, pos[t.y].xyz, pos[t.z].xyz, pos[t.w].xyz);
    let j = det3(f);
    // cof F = J F⁻ᵀ, written without the inverse so that it is defined at J = 0.
    let cof = mat3x3<f32>(cross_unfused(f[1], f[2]), cross_unfused(f[2], f[0]), cross_unfused(f[0], f[1]));
    // μF + λ'(J − α)·cof F, each term rounded before the sum.
    let a = sim.mu * f;
    let b = (sim.lambda * (j - sim.alpha)) * cof;
    let stress = mat3x3<f32>(
        unfused3(a[0]) + unfused3(b[0]),
        unfused3(a[1]) + unfused3(b[1]),
        unfused3(a[2]) + unfused3(b[2]),
    );
    let m = mm3(stress, transpose(tet_dm_inv(k)));
    let v = -tet_weight(k);
    let h = mat3x3<f32>(unfused3(v * m[0]), unfused3(v * m[1]), unfused3(v * m[2]));
    return corner_of(h, c);
}

// The force on vertex i of its tetrahedra, summed in adjacency order (CPU: `Elements::force_on`).
fn elements_force(i: u32) -> vec3<f32> {
    var f = vec3<f32>(0.0);
    if sim.tets == 0u {
        return f;
    }
    let range = tet_range(i);
    for (var e = range.x; e < range.y; e++) {
        let kc = tet_index[e];
        f += tet_corner_force(kc / 4u, kc % 4u);
    }
    return f;
}

// The eigenvalues (largest first) and unit eigenvectors (columns, right-handed) of the symmetric
// `a`, by cyclic Jacobi rotations (CPU: `fem::symmetric_eigen`, there in f64; here in f32, to
// f32's precision).
struct Eigen {
    values: vec3<f32>,
    vectors: mat3x3<f32>,
}

fn symmetric_eigen(a: mat3x3<f32>) -> Eigen {
    var m: array<array<f32, 3>, 3>;   // m[row][column]
    for (var i = 0u; i < 3u; i++) {
        for (var j = 0u; j < 3u; j++) {
            m[i][j] = 0.5 * (a[j][i] + a[i][j]);
        }
    }
    var v: array<array<f32, 3>, 3>;
    v[0] = array<f32, 3>(1.0, 0.0, 0.0);
    v[1] = array<f32, 3>(0.0, 1.0, 0.0);
    v[2] = array<f32, 3>(0.0, 0.0, 1.0);
    let pairs = array<vec2<u32>, 3>(vec2<u32>(0u, 1u), vec2<u32>(0u, 2u), vec2<u32>(1u, 2u));
    for (var sweep = 0u; sweep < 16u; sweep++) {
        let off = abs(m[0][1]) + abs(m[0][2]) + abs(m[1][2]);
        let scale = abs(m[0][0]) + abs(m[1][1]) + abs(m[2][2]);
        // f32's rounding leaves off-diagonals near 1e-7 of the scale.
        if off <= 1e-7 * scale || off == 0.0 {
            break;
        }
        for (var r = 0u; r < 3u; r++) {
            let p = pairs[r].x;
            let q = pairs[r].y;
            if m[p][q] == 0.0 {
                continue;
            }
            // The rotation in the (p, q) plane that zeroes m[p][q].
            let theta = (m[q][q] - m[p][p]) / (2.0 * m[p][q]);
            var t = select(-1.0, 1.0, theta >= 0.0) / (abs(theta) + sqrt(theta * theta + 1.0));
            if theta == 0.0 {
                t = 1.0;
            }
            let c = 1.0 / sqrt(t * t + 1.0);
            let s = t * c;
            for (var row = 0u; row < 3u; row++) {
                let x = m[row][p];
                let y = m[row][q];
                m[row][p] = c * x - s * y;
                m[row][q] = s * x + c * y;
            }
            for (var col = 0u; col < 3u; col++) {
                let x = m[p][col];
                let y = m[q][col];
                m[p][col] = c * x - s * y;
                m[q][col] = s * x + c * y;
            }
            for (var row = 0u; row < 3u; row++) {
                let x = v[row][p];
                let y = v[row][q];
                v[row][p] = c * x - s * y;
                v[row][q] = s * x + c * y;
            }
        }
    }
    // Largest first.
    var o = vec3<u32>(0u, 1u, 2u);
    let d = vec3<f32>(m[0][0], m[1][1], m[2][2]);
    if d[o.y] > d[o.x] {
        o = vec3<u32>(o.y, o.x, o.z);
    }
    if d[o.z] > d[o.y] {
        o = vec3<u32>(o.x, o.z, o.y);
    }
    if d[o.y] > d[o.x] {
        o = vec3<u32>(o.y, o.x, o.z);
    }
    let x = vec3<f32>(v[0][o.x], v[1][o.x], v[2][o.x]);
    let y = vec3<f32>(v[0][o.y], v[1][o.y], v[2][o.y]);
    return Eigen(vec3<f32>(d[o.x], d[o.y], d[o.z]), mat3x3<f32>(x, y, cross3(x, y)));
}

fn normalize3(v: vec3<f32>) -> vec3<f32> {
    return v * (1.0 / sqrt(dot3(v, v)));
}

// Any unit vector across the unit `u`.
fn across(u: vec3<f32>) -> vec3<f32> {
    var other = vec3<f32>(0.0, 1.0, 0.0);
    if abs(u.x) < 0.6 {
        other = vec3<f32>(1.0, 0.0, 0.0);
    }
    return normalize3(cross3(u, other));
}

// `F = U·diag(σ)·Vᵀ`, U and V rotations, σ₀ ≥ σ₁ ≥ |σ₂|, σ₂ negative where F is inverted
// (CPU: `fem::rotation_svd`).
struct Svd {
    u: mat3x3<f32>,
    sigma: vec3<f32>,
    v: mat3x3<f32>,
}

fn rotation_svd(f: mat3x3<f32>) -> Svd {
    let e = symmetric_eigen(mm3(transpose(f), f));
    let v = e.vectors;
    let s0 = sqrt(max(e.values.x, 0.0));
    let s1 = sqrt(max(e.values.y, 0.0));
    let scale = max(s0, 1e-30);
    var u0 = vec3<f32>(1.0, 0.0, 0.0);
    if s0 > 1e-12 {
        u0 = mv3(f, v[0]) / s0;
    }
    let fv1 = mv3(f, v[1]);
    var u1 = fv1 - dot3(u0, fv1) * u0;
    if sqrt(dot3(u1, u1)) > 1e-6 * scale {
        u1 = normalize3(u1);
    } else {
        u1 = across(u0);
    }
    let u2 = cross3(u0, u1);
    let s2 = dot3(u2, mv3(f, v[2]));
    return Svd(mat3x3<f32>(u0, u1, u2), vec3<f32>(s0, s1, s2), v);
}

// A tetrahedron's projected stiffness with its rest shape folded in (CPU: `fem::TetStiffness`):
// U, W = D_m⁻¹·V, V₀ times the 3×3 block on the stretches, and V₀ times the shears' weights
// per pair (1,2), (0,2), (0,1): T(d)_ij = a·d_ij + b·d_ji off the diagonal, with a and b the
// half sum and half difference of the pair's eigenvalues on δF̂_ij + δF̂_ji and δF̂_ij − δF̂_ji,
// each clamped at 0.
struct Tangent {
    u: mat3x3<f32>,
    w: mat3x3<f32>,
    stretch: mat3x3<f32>,
    a: vec3<f32>,
    b: vec3<f32>,
}

// Tetrahedron k's stiffness at its deformation f.
fn tangent_at(f: mat3x3<f32>, k: u32) -> Tangent {
    let svd = rotation_svd(f);
    let sigma = svd.sigma;
    let mu = sim.mu;
    let lambda = sim.lambda;
    let j = sigma.x * sigma.y * sigma.z;
    let s = lambda * (j - sim.alpha);
    // ∂J/∂σ_i: the product of the other two.
    let c = vec3<f32>(sigma.y * sigma.z, sigma.x * sigma.z, sigma.x * sigma.y);
    var stretch = mat3x3<f32>(lambda * c.x * c, lambda * c.y * c, lambda * c.z * c)
        + mat3x3<f32>(vec3<f32>(mu, 0.0, 0.0), vec3<f32>(0.0, mu, 0.0), vec3<f32>(0.0, 0.0, mu));
    // ∂²J/∂σ_i∂σ_j: the third σ, off the diagonal.
    let cross_terms = mat3x3<f32>(
        vec3<f32>(0.0, sigma.z, sigma.y),
        vec3<f32>(sigma.z, 0.0, sigma.x),
        vec3<f32>(sigma.y, sigma.x, 0.0),
    );
    stretch += s * cross_terms;
    let e = symmetric_eigen(stretch);
    let q = e.vectors;
    let l = max(e.values, vec3<f32>(0.0));
    let ql = mat3x3<f32>(q[0] * l.x, q[1] * l.y, q[2] * l.z);
    stretch = mm3(ql, transpose(q));
    let plus = max(mu - s * sigma, vec3<f32>(0.0));
    let minus = max(mu + s * sigma, vec3<f32>(0.0));
    let v0 = tet_weight(k);
    let half = 0.5 * v0;
    return Tangent(svd.u, mm3(tet_dm_inv(k), svd.v), v0 * stretch, half * (plus + minus), half * (plus - minus));
}

// `V₀·δP·D_m⁻ᵀ` of a tetrahedron for its corners' displacements: `U·T(Uᵀ·D_s·W)·Wᵀ` (CPU:
// `TetStiffness::product`).
fn stiffness_product(t: Tangent, u0: vec3<f32>, u1: vec3<f32>, u2: vec3<f32>, u3: vec3<f32>) -> mat3x3<f32> {
    let d = mm3(transpose(t.u), mm3(mat3x3<f32>(u1 - u0, u2 - u0, u3 - u0), t.w));   // d[j][i] = D_ij
    let diag = mv3(t.stretch, vec3<f32>(d[0][0], d[1][1], d[2][2]));
    var p = mat3x3<f32>(vec3<f32>(diag.x, 0.0, 0.0), vec3<f32>(0.0, diag.y, 0.0), vec3<f32>(0.0, 0.0, diag.z));
    let pairs = array<vec2<u32>, 3>(vec2<u32>(1u, 2u), vec2<u32>(0u, 2u), vec2<u32>(0u, 1u));
    for (var k = 0u; k < 3u; k++) {
        let i = pairs[k].x;
        let j = pairs[k].y;
        p[j][i] = t.a[k] * d[j][i] + t.b[k] * d[i][j];
        p[i][j] = t.a[k] * d[i][j] + t.b[k] * d[j][i];
    }
    return mm3(mm3(t.u, p), transpose(t.w));
}

// The diagonal block of `−K` of a tetrahedron at its corner c (CPU:
// `TetStiffness::diagonal_blocks`).
fn diagonal_block(t: Tangent, c: u32) -> mat3x3<f32> {
    var cols: array<vec3<f32>, 3>;
    for (var a = 0u; a < 3u; a++) {
        var e = vec3<f32>(0.0);
        e[a] = 1.0;
        var u = array<vec3<f32>, 4>(vec3<f32>(0.0), vec3<f32>(0.0), vec3<f32>(0.0), vec3<f32>(0.0));
        u[c] = e;
        cols[a] = corner_of(stiffness_product(t, u[0], u[1], u[2], u[3]), c);
    }
    return mat3x3<f32>(cols[0], cols[1], cols[2]);
}
