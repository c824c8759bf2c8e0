//! Finite elements that honour Poisson's ratio (DESIGN §12, `model = "neo-hookean"`): linear
//! tetrahedra of a stable Neo-Hookean material (Smith, de Goes and Kim 2018, without its
//! `log(I_C + 1)` term), on a lattice's cubes (six tetrahedra each, the Freudenthal split that
//! neighbouring cubes share faces with) or on a `.vtu`/`.msh` mesh's own tetrahedra.
//!
//! **Energy.** Per unit rest volume, with `F` the deformation gradient, `I_C = tr(FᵀF)` and
//! `J = det F`:
//!
//! ```text
//! Ψ = μ/2 (I_C − 3) + λ'/2 (J − α)²,   λ' = λ + μ,   α = 1 + μ/λ'
//! ```
//!
//! so that the rest shape is stress-free and, at small strain, the material is linear elastic
//! with Lamé's `μ` and `λ` (hence the file's Young's modulus and ν). It stays well defined
//! through inversion (`J ≤ 0`), which a contact can cause, and does not lock at ν → 0.5 as
//! badly as a linear element with a `log J` term; at ν = 0.49 a lattice of linear tetrahedra
//! still stiffens in bending (measured in tests/fem.rs).
//!
//! **Forces.** `P = μF + λ'(J − α)·cof F`, and each tetrahedron gives its corners `1..3` the
//! columns of `−V₀·P·D_m⁻ᵀ` and corner 0 minus their sum. Each vertex gathers over its
//! tetrahedra in a fixed order, so the sum is the same on any number of threads.

use glam::{Mat3, UVec3, Vec3};
use std::collections::HashMap;

use voxcollide::error::Error;

/// The tetrahedra of a body and their material.
#[derive(Clone, Debug, PartialEq)]
pub struct Elements {
    /// Each tetrahedron's corners, positively oriented at rest.
    pub tets: Vec<[u32; 4]>,
    /// Each tetrahedron's `D_m⁻¹` (its rest edges from corner 0, as columns, inverted).
    pub dm_inv: Vec<Mat3>,
    /// Each tetrahedron's rest volume.
    pub volume: Vec<f32>,
    /// Lamé's `μ` (internal stress units).
    pub mu: f32,
    /// `λ' = λ + μ` of the energy.
    pub lambda: f32,
    /// Per vertex, its `(tetrahedron, corner)` pairs in CSR form: those of vertex `i` are
    /// `adjacency[offsets[i]..offsets[i + 1]]`.
    pub offsets: Vec<u32>,
    /// See `offsets`.
    pub adjacency: Vec<[u32; 2]>,
}

/// Lamé's `(μ, λ)` of Young's modulus `e` and Poisson's ratio `nu`.
#[must_use]
pub fn lame(e: f64, nu: f64) -> (f64, f64) {
    (e / (2.0 * (1.0 + nu)), e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)))
}

impl Elements {
    /// The elements of `tets` over `rest` (turned where given in the negative order), for
    /// Young's modulus `e` and Poisson's ratio `nu` (internal stress units).
    ///
    /// # Errors
    /// [`Error::Invalid`] for an index out of range, a flat tetrahedron, or a modulus or ratio
    /// out of range.
    pub fn new(rest: &[Vec3], tets: &[[u32; 4]], e: f64, nu: f64) -> Result<Elements, Error> {
        let invalid = |what, value: String, rule: &str| Error::Invalid { what, value, rule: rule.into() };
        if !(e.is_finite() && e > 0.0) {
            return Err(invalid("Young's modulus", e.to_string(), "must be finite and positive"));
        }
        if !(nu.is_finite() && (0.0..0.5).contains(&nu)) {
            return Err(invalid("Poisson's ratio", nu.to_string(), "must be in [0, 0.5)"));
        }
        if tets.is_empty() {
            return Err(invalid("tetrahedra", "none".into(), "a finite-element body needs at least one"));
        }
        let n = rest.len();
        let (mut out, mut dm_inv, mut volume) =
            (Vec::with_capacity(tets.len()), Vec::with_capacity(tets.len()), Vec::with_capacity(tets.len()));
        for t in tets {
            if t.iter().any(|&v| v as usize >= n) {
                return Err(invalid("tetrahedron", format!("{t:?}"), &format!("indices must be below {n}")));
            }
            let mut t = *t;
            let dm = |t: &[u32; 4]| {
                let p = t.map(|v| rest[v as usize]);
                Mat3::from_cols(p[1] - p[0], p[2] - p[0], p[3] - p[0])
            };
            let mut m = dm(&t);
            if m.determinant() < 0.0 {
                t.swap(2, 3);
                m = dm(&t);
            }
            let det = m.determinant();
            let scale = m.x_axis.length() * m.y_axis.length() * m.z_axis.length();
            if !(det > 1e-6 * scale && det.is_finite()) {
                return Err(invalid(
                    "tetrahedron",
                    format!("{t:?}"),
                    "is flat: its corners must span a volume",
                ));
            }
            out.push(t);
            dm_inv.push(m.inverse());
            volume.push(det / 6.0);
        }
        let mut offsets = vec![0u32; n + 1];
        for t in &out {
            for &v in t {
                offsets[v as usize + 1] += 1;
            }
        }
        for i in 0..n {
            offsets[i + 1] += offsets[i];
        }
        let mut fill = offsets.clone();
        let mut adjacency = vec![[0u32; 2]; offsets[n] as usize];
        for (k, t) in out.iter().enumerate() {
            for (c, &v) in t.iter().enumerate() {
                adjacency[fill[v as usize] as usize] = [k as u32, c as u32];
                fill[v as usize] += 1;
            }
        }
        let (mu, lambda) = lame(e, nu);
        Ok(Elements {
            tets: out,
            dm_inv,
            volume,
            mu: mu as f32,
            lambda: (lambda + mu) as f32,
            offsets,
            adjacency,
        })
    }

    /// `α = 1 + μ/λ'`.
    fn alpha(&self) -> f32 {
        1.0 + self.mu / self.lambda
    }

    /// The force of tetrahedron `k` on its corner `corner` at positions `pos`.
    #[must_use]
    pub fn corner_force(&self, pos: &[Vec3], k: usize, corner: usize) -> Vec3 {
        let t = self.tets[k];
        let p = t.map(|v| pos[v as usize]);
        let ds = Mat3::from_cols(p[1] - p[0], p[2] - p[0], p[3] - p[0]);
        let f = ds * self.dm_inv[k];
        let j = f.determinant();
        // cof F = J F⁻ᵀ, written without the inverse so that it is defined at J = 0.
        let cof =
            Mat3::from_cols(f.y_axis.cross(f.z_axis), f.z_axis.cross(f.x_axis), f.x_axis.cross(f.y_axis));
        let stress = self.mu * f + (self.lambda * (j - self.alpha())) * cof;
        let h = -self.volume[k] * (stress * self.dm_inv[k].transpose());
        match corner {
            0 => -(h.x_axis + h.y_axis + h.z_axis),
            1 => h.x_axis,
            2 => h.y_axis,
            _ => h.z_axis,
        }
    }

    /// The force on vertex `i`: its tetrahedra's, summed in adjacency order.
    #[must_use]
    pub fn force_on(&self, pos: &[Vec3], i: usize) -> Vec3 {
        let mut f = Vec3::ZERO;
        for &[k, c] in &self.adjacency[self.offsets[i] as usize..self.offsets[i + 1] as usize] {
            f += self.corner_force(pos, k as usize, c as usize);
        }
        f
    }

    /// Per vertex, a bound on `ω²·mass` (Gershgorin over its tetrahedra's stiffness: the
    /// P-wave modulus `λ + 2μ` times `V₀·|∇N_a|·Σ_b|∇N_b|`, doubled for large strain).
    #[must_use]
    pub fn stiffness_bound(&self, n: usize) -> Vec<f32> {
        let p_wave = self.lambda + self.mu; // λ' + μ = λ + 2μ
        let mut bound = vec![0.0f32; n];
        for (k, t) in self.tets.iter().enumerate() {
            let g = self.dm_inv[k].transpose();
            let grads = [-(g.x_axis + g.y_axis + g.z_axis), g.x_axis, g.y_axis, g.z_axis];
            let sum: f32 = grads.iter().map(|g| g.length()).sum();
            for (c, &v) in t.iter().enumerate() {
                bound[v as usize] += 2.0 * p_wave * self.volume[k] * grads[c].length() * sum;
            }
        }
        bound
    }
}

/// The tetrahedra of a lattice of spacing `h` whose vertices sit at `rest`: six per cube whose
/// eight corners are all vertices (the Freudenthal split along each cube's main diagonal, so
/// that neighbouring cubes share their faces' diagonals).
#[must_use]
pub fn lattice_tets(rest: &[Vec3], h: f32) -> Vec<[u32; 4]> {
    let Some(origin) = rest.iter().copied().reduce(Vec3::min) else { return Vec::new() };
    let key = |p: Vec3| ((p - origin) / h).round().as_ivec3();
    let at: HashMap<_, u32> = rest.iter().enumerate().map(|(i, p)| (key(*p), i as u32)).collect();
    let axes = [UVec3::X, UVec3::Y, UVec3::Z].map(|a| a.as_ivec3());
    let paths = [[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]];
    let mut tets = Vec::new();
    let mut corners: Vec<_> = at.keys().copied().collect();
    corners.sort_by_key(|c| (c.z, c.y, c.x));
    for c in corners {
        let cube = |d: voxcollide::glam::IVec3| at.get(&(c + d)).copied();
        let all =
            (0..8).all(|b| cube(voxcollide::glam::IVec3::new(b & 1, (b >> 1) & 1, (b >> 2) & 1)).is_some());
        if !all {
            continue;
        }
        for path in paths {
            let a = axes[path[0]];
            let b = a + axes[path[1]];
            let corners = [voxcollide::glam::IVec3::ZERO, a, b, voxcollide::glam::IVec3::ONE];
            tets.push(corners.map(|d| cube(d).unwrap_or(0)));
        }
    }
    tets
}
