//! The Neo-Hookean material (WGSL twin: `shaders/elements.wgsl`): finite elements that honour Poisson's ratio (docs/design.md §12, `model = "neo-hookean"`): linear
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
//!
//! **Stiffness** (for the implicit integrator, [`Tangent`]). `∂P/∂F` in the frame of `F`'s
//! singular vectors (`F = U·diag(σ)·Vᵀ`, rotations, `σ₂ < 0` where inverted) is a 3×3 block on
//! the stretches, `μ·I + λ'·c·cᵀ + s·S` (`c_i = ∂J/∂σ_i`, `s = λ'(J − α)`, `S_ij = σ_k` off the
//! diagonal), and per pair of shears `(i, j)` the eigenvalues `μ − s·σ_k` on `δF̂_ij + δF̂_ji`
//! and `μ + s·σ_k` on `δF̂_ij − δF̂_ji` (Teran et al. 2005, for this energy in closed form, with
//! no division by `σ_i − σ_j`). Each block's negative eigenvalues are clamped to 0, so that the
//! implicit solve's matrix stays positive definite under compression and inversion; at rest
//! nothing is clamped and the tangent is linear elasticity's. Dropping the `s·∂²J/∂F²` term
//! instead (Gauss–Newton) was not done: it halves the shear stiffness at rest, and a step of
//! the implicit integrator then overshoots a shear by its whole size.

use glam::{DMat3, DVec3, Mat3, Mat3A, UVec3, Vec3, Vec3A};
use std::collections::HashMap;

use super::{Linearised, Material};
use crate::body::{MassSpring, PAR_CHUNK, StepInputs};
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
    /// Each tetrahedron's Young's modulus over the material's (`mu`, `lambda`): 1, or a layer's
    /// over the body's ([`Elements::weight`]). Poisson's ratio is the body's throughout, so
    /// `μ`, `λ` and the energy scale by it and `α` does not.
    pub modulus: Vec<f32>,
    /// Lamé's `μ` (internal stress units).
    pub mu: f32,
    /// `λ' = λ + μ` of the energy.
    pub lambda: f32,
    /// Per vertex, its `(tetrahedron, corner)` pairs in CSR form: those of vertex `i` are
    /// `adjacency[offsets[i]..offsets[i + 1]]`.
    pub offsets: Vec<u32>,
    /// See `offsets`.
    pub adjacency: Vec<[u32; 2]>,
    /// Where each tetrahedron's stiffness goes in the body's ([`Pattern`]).
    pattern: Pattern,
    /// Each tetrahedron's frame of singular vectors at its last assembly, where the next one's
    /// decomposition starts ([`Elements::assemble`]).
    frames: Frames,
}

/// The frames the last assembly's decompositions ended in, one per tetrahedron, and the room
/// its blocks were written in: a cache of work, not part of the material, so two bodies with
/// the same elements are equal whatever their caches hold, and a clone starts with a copy of
/// its original's frames.
#[derive(Debug, Default)]
struct Frames(std::sync::Mutex<Cache>);

/// What [`Frames`] keeps.
#[derive(Debug, Default)]
struct Cache {
    /// Per tetrahedron, the frame its last decomposition ended in.
    frames: Vec<Mat3>,
    /// Per tetrahedron, room for its sixteen blocks ([`Elements::assemble`]): every one is
    /// written before it is read, so it is kept, not cleared, from one assembly to the next.
    blocks: Vec<[Mat3; 16]>,
}

impl Clone for Frames {
    fn clone(&self) -> Frames {
        let frames = self.0.lock().map_or_else(|e| e.into_inner().frames.clone(), |c| c.frames.clone());
        Frames(std::sync::Mutex::new(Cache { frames, blocks: Vec::new() }))
    }
}

impl PartialEq for Frames {
    fn eq(&self, _: &Frames) -> bool {
        true
    }
}

/// The sparsity of the elements' stiffness over the vertices, for the implicit solve's
/// assembled `−K` ([`Linearised`]): row `i` holds a 3×3 block per vertex that shares a
/// tetrahedron with `i` (itself included), ascending, in CSR form; each tetrahedron knows the
/// slot of each of its sixteen corner pairs.
#[derive(Clone, Debug, PartialEq)]
struct Pattern {
    /// Row `i`'s slots are `offsets[i]..offsets[i + 1]`.
    offsets: Vec<u32>,
    /// Per slot, its column (the other vertex).
    columns: Vec<u32>,
    /// Per tetrahedron, per corner pair `4·row + column`, its slot.
    slots: Vec<[u32; 16]>,
}

impl Pattern {
    fn new(n: usize, tets: &[[u32; 4]]) -> Pattern {
        let mut rows: Vec<Vec<u32>> = vec![Vec::new(); n];
        for t in tets {
            for &a in t {
                rows[a as usize].extend(t);
            }
        }
        let mut offsets = Vec::with_capacity(n + 1);
        let mut columns = Vec::new();
        offsets.push(0);
        for row in &mut rows {
            row.sort_unstable();
            row.dedup();
            columns.extend_from_slice(row);
            offsets.push(columns.len() as u32);
        }
        let slots = tets
            .iter()
            .map(|t| {
                std::array::from_fn(|pair| {
                    let (a, b) = (t[pair / 4] as usize, t[pair % 4]);
                    let row = &columns[offsets[a] as usize..offsets[a + 1] as usize];
                    offsets[a] + row.binary_search(&b).unwrap_or(0) as u32
                })
            })
            .collect();
        Pattern { offsets, columns, slots }
    }
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
        let modulus = vec![1.0; out.len()];
        let pattern = Pattern::new(n, &out);
        Ok(Elements {
            tets: out,
            dm_inv,
            volume,
            modulus,
            mu: mu as f32,
            lambda: (lambda + mu) as f32,
            offsets,
            adjacency,
            pattern,
            frames: Frames::default(),
        })
    }

    /// Tetrahedron `k`'s rest volume times its [`modulus`](Elements::modulus): its energy
    /// is that times `Ψ(F)` of the material, so its forces and stiffness scale by it. (With a
    /// modulus of 1, the volume itself, to the bit.)
    #[must_use]
    pub fn weight(&self, k: usize) -> f32 {
        self.volume[k] * self.modulus[k]
    }

    /// `α = 1 + μ/λ'`.
    pub(crate) fn alpha(&self) -> f32 {
        1.0 + self.mu / self.lambda
    }

    /// The force of tetrahedron `k` on its corner `corner` at positions `pos`.
    #[must_use]
    pub fn corner_force(&self, pos: &[Vec3], k: usize, corner: usize) -> Vec3 {
        corner_of(&self.tet_force(pos, k), corner)
    }

    /// Tetrahedron `k`'s `−V₀·P·D_m⁻ᵀ` at positions `pos`: its forces on corners 1..=3 as
    /// columns ([`corner_of`] gives each corner's, corner 0's minus their sum).
    #[must_use]
    pub fn tet_force(&self, pos: &[Vec3], k: usize) -> Mat3 {
        let t = self.tets[k];
        let p = t.map(|v| pos[v as usize]);
        let ds = Mat3::from_cols(p[1] - p[0], p[2] - p[0], p[3] - p[0]);
        let f = ds * self.dm_inv[k];
        let j = f.determinant();
        // cof F = J F⁻ᵀ, written without the inverse so that it is defined at J = 0.
        let cof =
            Mat3::from_cols(f.y_axis.cross(f.z_axis), f.z_axis.cross(f.x_axis), f.x_axis.cross(f.y_axis));
        let stress = self.mu * f + (self.lambda * (j - self.alpha())) * cof;
        -self.weight(k) * (stress * self.dm_inv[k].transpose())
    }

    /// Every tetrahedron's [`tet_force`](Self::tet_force) at `pos`, once each.
    #[must_use]
    pub fn tet_forces(&self, pos: &[Vec3]) -> Vec<Mat3> {
        use rayon::prelude::*;
        (0..self.tets.len()).into_par_iter().with_min_len(PAR_CHUNK).map(|k| self.tet_force(pos, k)).collect()
    }

    /// The force on vertex `i` from its tetrahedra's [`tet_forces`](Self::tet_forces),
    /// summed in adjacency order: [`force_on`](Self::force_on)'s bits.
    #[must_use]
    pub fn gathered(&self, forces: &[Mat3], i: usize) -> Vec3 {
        self.sum_corners(i, |k, c| corner_of(&forces[k], c))
    }

    /// The force on vertex `i`: its tetrahedra's, summed in adjacency order.
    #[must_use]
    pub fn force_on(&self, pos: &[Vec3], i: usize) -> Vec3 {
        self.sum_corners(i, |k, c| self.corner_force(pos, k, c))
    }

    /// `corner(k, c)` summed over vertex `i`'s tetrahedra `k` (it their corner `c`), in
    /// adjacency order.
    fn sum_corners(&self, i: usize, corner: impl Fn(usize, usize) -> Vec3) -> Vec3 {
        let mut f = Vec3::ZERO;
        for &[k, c] in &self.adjacency[self.offsets[i] as usize..self.offsets[i + 1] as usize] {
            f += corner(k as usize, c as usize);
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
                bound[v as usize] += 2.0 * p_wave * self.weight(k) * grads[c].length() * sum;
            }
        }
        bound
    }
}

/// The elements as a [`Material`]: each vertex's tetrahedra, gathered in adjacency order.
impl Material for Elements {
    fn add_force(
        &self,
        _body: &MassSpring,
        pos: &[Vec3],
        _vel: &[Vec3],
        _rest_scale: f32,
        i: usize,
        prepared: &[Mat3],
        f: &mut Vec3,
    ) {
        // Summed first, then added: as `shaders/elements.wgsl`'s `elements_force`.
        *f += if prepared.is_empty() { self.force_on(pos, i) } else { self.gathered(prepared, i) };
    }

    fn prepare(&self, _body: &MassSpring, pos: &[Vec3]) -> Vec<Mat3> {
        self.tet_forces(pos)
    }

    fn for_each_term(
        &self,
        _body: &MassSpring,
        pos: &[Vec3],
        _rest_scale: f32,
        i: usize,
        prepared: &[Mat3],
        term: &mut dyn FnMut(Vec3),
    ) {
        for &[k, c] in &self.adjacency[self.offsets[i] as usize..self.offsets[i + 1] as usize] {
            let (k, c) = (k as usize, c as usize);
            term(if prepared.is_empty() { self.corner_force(pos, k, c) } else { corner_of(&prepared[k], c) });
        }
    }

    fn stiffness_bounds(&self, body: &MassSpring, _s_max: f32) -> Vec<f32> {
        self.stiffness_bound(body.len())
    }

    fn linearise(&self, body: &MassSpring, inputs: &StepInputs) -> Box<dyn Linearised> {
        Box::new(LinearElements { blocks: self.assemble(&body.pos), h: inputs.dt })
    }
}

impl Elements {
    /// The projected stiffness `−K` at `pos`, assembled: per slot of the body's pattern, its
    /// block (row vertex, column vertex), each row summed over the row vertex's tetrahedra in
    /// adjacency order (the same on any number of threads).
    ///
    /// A conjugate-gradient product is then a sparse row per vertex (15 blocks on a lattice)
    /// instead of every tetrahedron's product again at each iteration: at ν = 0.49 the solve
    /// takes 26 iterations a step on the bunny press of docs/integrator.md, and each one
    /// re-derived six tetrahedra's stiffness per vertex.
    #[must_use]
    pub fn assemble(&self, pos: &[Vec3]) -> Vec<Mat3> {
        use rayon::prelude::*;
        // Each tetrahedron's blocks written where they are kept, from its stiffness made there
        // and then: no list of stiffnesses, and no copy of the blocks (a tenth of a solve's
        // time on the patient, 2026-12-06).
        let mut cache = self.frames.0.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        let Cache { frames, blocks: per_tet } = &mut *cache;
        let fresh = self.frames_ready(frames);
        per_tet.resize(self.tets.len(), [Mat3::ZERO; 16]);
        per_tet
            .par_iter_mut()
            .zip(frames.par_iter_mut())
            .enumerate()
            .with_min_len(1024)
            .for_each(|(k, (out, frame))| self.stiffness_from(pos, k, frame, fresh).blocks_into(out));
        let per_tet = &*per_tet;
        let p = &self.pattern;
        let mut blocks = vec![Mat3::ZERO; p.columns.len()];
        let mut rows: Vec<&mut [Mat3]> = Vec::with_capacity(p.offsets.len());
        let mut rest = blocks.as_mut_slice();
        for w in p.offsets.windows(2) {
            let (row, tail) = rest.split_at_mut((w[1] - w[0]) as usize);
            rows.push(row);
            rest = tail;
        }
        rows.into_par_iter().enumerate().with_min_len(PAR_CHUNK).for_each(|(i, row)| {
            let start = p.offsets[i];
            for &[k, c] in &self.adjacency[self.offsets[i] as usize..self.offsets[i + 1] as usize] {
                let (k, c) = (k as usize, c as usize);
                for d in 0..4 {
                    row[(p.slots[k][4 * c + d] - start) as usize] += per_tet[k][4 * c + d];
                }
            }
        });
        blocks
    }
}

/// The elements' linearisation: their projected stiffness at the step's start, assembled over
/// the vertices ([`Elements::assemble`]); a product is a sparse row per vertex.
struct LinearElements {
    /// Per slot of the elements' pattern, its block of `−K`.
    blocks: Vec<Mat3>,
    h: f32,
}

impl Linearised for LinearElements {
    fn add_product(
        &self,
        body: &MassSpring,
        u: &[Vec3],
        _: &[Mat3],
        i: usize,
        stiff_only: bool,
        r: &mut Vec3,
    ) {
        let Some(e) = body.elements.as_ref() else { return };
        let p = &e.pattern;
        let mut sum = Vec3::ZERO;
        for s in p.offsets[i] as usize..p.offsets[i + 1] as usize {
            sum += self.blocks[s] * u[p.columns[s] as usize];
        }
        let h2 = if stiff_only { 1.0 } else { self.h * self.h };
        *r += h2 * sum;
    }

    fn add_diagonal(&self, body: &MassSpring, i: usize, b: &mut Mat3) {
        let Some(e) = body.elements.as_ref() else { return };
        let p = &e.pattern;
        let row = p.offsets[i] as usize..p.offsets[i + 1] as usize;
        if let Ok(s) = p.columns[row.clone()].binary_search(&(i as u32)) {
            *b += (self.h * self.h) * self.blocks[row.start + s];
        }
    }
}

/// Three tetrahedra per triangular prism, `[a, b, c, d, e, f]` with `abc` and `def` its two
/// triangles and `ad`, `be`, `cf` its three other edges, so that each quad face is cut along
/// the diagonal through its smallest vertex index (Dompierre, Labbé, Vallet and Camarero
/// 1999): two prisms that share a quad face cut it alike, so the tetrahedra of a mesh of
/// prisms share whole faces.
#[must_use]
pub fn prism_tets(prisms: &[[u32; 6]]) -> Vec<[u32; 4]> {
    let mut out = Vec::with_capacity(3 * prisms.len());
    for p in prisms {
        // Relabel so that the smallest index is `a`: the other triangle first if it is there,
        // then a turn of both triangles.
        let m = (0..6).min_by_key(|&i| p[i]).unwrap_or(0);
        let q = if m < 3 { *p } else { [p[3], p[4], p[5], p[0], p[1], p[2]] };
        let r = m % 3;
        let [a, b, c, d, e, f] =
            [q[r], q[(r + 1) % 3], q[(r + 2) % 3], q[3 + r], q[3 + (r + 1) % 3], q[3 + (r + 2) % 3]];
        // The faces at `a` are cut through it (a–e, a–f); the face bcfe through its smallest.
        if b.min(f) < c.min(e) {
            out.extend([[a, b, c, f], [a, b, f, e], [a, e, f, d]]);
        } else {
            out.extend([[a, b, c, e], [a, e, c, f], [a, e, f, d]]);
        }
    }
    out
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

/// The eigenvalues and unit eigenvectors (columns, right-handed) of the symmetric `a`, by
/// cyclic Jacobi rotations in `f64`, largest eigenvalue first.
#[allow(clippy::needless_range_loop)] // rows p and q of one matrix, by index
fn symmetric_eigen(a: Mat3) -> (Vec3, Mat3) {
    symmetric_eigen_from(a, None)
}

/// [`symmetric_eigen`] with its rotations started from the frame `start` (a decomposition of a
/// nearby matrix: the last step's, [`Frames`]) instead of the axes: `a` is first taken into
/// that frame, where it is nearly diagonal, and fewer rotations are left to do. The frame is
/// made orthonormal again in `f64` first (Gram–Schmidt); one that is not finite or not a
/// frame starts from the axes.
fn symmetric_eigen_from(a: Mat3, start: Option<Mat3>) -> (Vec3, Mat3) {
    let sym = ((a + a.transpose()) * 0.5).as_dmat3();
    let q = start.and_then(orthonormal);
    // m ← qᵀ·m·q, kept symmetric; v starts as q (its columns the frame's axes).
    let (sym, q) = match q {
        Some(q) => {
            let qmq = q.transpose() * (sym * q);
            ((qmq + qmq.transpose()) * 0.5, q)
        }
        None => (sym, DMat3::IDENTITY),
    };
    // The rotations below work on entries by index: `m[i][j]` (symmetric, so rows or columns
    // alike) and `v[i][j]`, row `i` and column `j` of the frame.
    let mut m = sym.to_cols_array_2d();
    let mut v = q.transpose().to_cols_array_2d();
    for _ in 0..16 {
        let off = m[0][1].abs() + m[0][2].abs() + m[1][2].abs();
        let scale = m[0][0].abs() + m[1][1].abs() + m[2][2].abs();
        if off <= 1e-15 * scale || off == 0.0 {
            break;
        }
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            if m[p][q] == 0.0 {
                continue;
            }
            // The rotation in the (p, q) plane that zeroes m[p][q], applied to the five
            // entries it changes (both halves kept, m symmetric) and to v's columns p and q, in
            // Rutishauser's form with τ = s/(1 + c) (Numerical Recipes' `jacobi`): a quarter
            // of the arithmetic of rotating m's rows and columns whole.
            let apq = m[p][q];
            let theta = (m[q][q] - m[p][p]) / (2.0 * apq);
            let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
            let t = if theta == 0.0 { 1.0 } else { t };
            let c = 1.0 / (t * t + 1.0).sqrt();
            let s = t * c;
            let tau = s / (1.0 + c);
            m[p][p] -= t * apq;
            m[q][q] += t * apq;
            m[p][q] = 0.0;
            m[q][p] = 0.0;
            let r = 3 - p - q;
            let (g, h) = (m[r][p], m[r][q]);
            let (gp, hq) = (g - s * (h + g * tau), h + s * (g - h * tau));
            (m[r][p], m[p][r], m[r][q], m[q][r]) = (gp, gp, hq, hq);
            for row in &mut v {
                let (g, h) = (row[p], row[q]);
                row[p] = g - s * (h + g * tau);
                row[q] = h + s * (g - h * tau);
            }
        }
    }
    let mut order = [0usize, 1, 2];
    order.sort_by(|&i, &j| m[j][j].total_cmp(&m[i][i]));
    let values = Vec3::from_array(order.map(|k| m[k][k] as f32));
    let col = |k: usize| Vec3::new(v[0][k] as f32, v[1][k] as f32, v[2][k] as f32);
    let (x, y) = (col(order[0]), col(order[1]));
    (values, Mat3::from_cols(x, y, x.cross(y)))
}

/// `q`'s columns made orthonormal in `f64` (Gram–Schmidt, right-handed); `None` where they
/// are not finite or nearly dependent.
fn orthonormal(q: Mat3) -> Option<DMat3> {
    let unit = |a: DVec3| {
        let n = a.length();
        (n.is_finite() && n > 0.5).then(|| a / n)
    };
    let x = unit(q.x_axis.as_dvec3())?;
    let y = q.y_axis.as_dvec3();
    let y = unit(y - x.dot(y) * x)?;
    Some(DMat3::from_cols(x, y, x.cross(y)))
}

/// Any unit vector across `u` (unit).
fn across(u: Vec3) -> Vec3 {
    let other = if u.x.abs() < 0.6 { Vec3::X } else { Vec3::Y };
    u.cross(other).normalize()
}

/// `F = U·diag(σ)·Vᵀ` with `U`, `V` rotations and `σ₀ ≥ σ₁ ≥ |σ₂|`, `σ₂` negative where `F`
/// is inverted (so that `J = σ₀σ₁σ₂`).
fn rotation_svd(f: Mat3, start: Option<Mat3>) -> (Mat3, Vec3, Mat3) {
    let (values, v) = symmetric_eigen_from(f.transpose() * f, start);
    let s0 = values.x.max(0.0).sqrt();
    let s1 = values.y.max(0.0).sqrt();
    let scale = s0.max(1e-30);
    let u0 = if s0 > 1e-12 { (f * v.x_axis) / s0 } else { Vec3::X };
    let fv1 = f * v.y_axis;
    let u1 = fv1 - u0.dot(fv1) * u0;
    let u1 = if u1.length() > 1e-6 * scale { u1.normalize() } else { across(u0) };
    let u2 = u0.cross(u1);
    let s2 = u2.dot(f * v.z_axis);
    (Mat3::from_cols(u0, u1, u2), Vec3::new(s0, s1, s2), v)
}

/// The stiffness of one tetrahedron's material at a deformation `F`, projected to be positive
/// semi-definite (Teran, Sifakis, Irving and Fedkiw 2005): `∂P/∂F` in the frame of `F`'s
/// singular vectors, where it is one 3×3 block on the stretches and three 2×2 blocks on the
/// pairs of shears, each clamped at zero eigenvalue. The implicit integrator's element Hessian.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tangent {
    u: Mat3,
    v: Mat3,
    /// The 3×3 block on the stretches `δF̂_ii`, projected.
    stretch: Mat3,
    /// Per pair `(1,2), (0,2), (0,1)` (the pair across axis `k`): the eigenvalues on
    /// `δF̂_ij + δF̂_ji` and on `δF̂_ij − δF̂_ji`, clamped at 0.
    shear: [[f32; 2]; 3],
}

impl Tangent {
    /// `δP = ∂P/∂F : δF`.
    #[must_use]
    pub fn apply(&self, df: Mat3) -> Mat3 {
        let d = self.u.transpose() * df * self.v;
        let at = |i: usize, j: usize| d.col(j)[i];
        let diag = self.stretch * Vec3::new(at(0, 0), at(1, 1), at(2, 2));
        let mut p = [[0.0f32; 3]; 3]; // p[column][row]
        p[0][0] = diag.x;
        p[1][1] = diag.y;
        p[2][2] = diag.z;
        for (k, (i, j)) in [(1usize, 2usize), (0, 2), (0, 1)].into_iter().enumerate() {
            let (sym, anti) = (0.5 * (at(i, j) + at(j, i)), 0.5 * (at(i, j) - at(j, i)));
            let [plus, minus] = self.shear[k];
            p[j][i] = plus * sym + minus * anti;
            p[i][j] = plus * sym - minus * anti;
        }
        let p = Mat3::from_cols_array_2d(&p);
        self.u * p * self.v.transpose()
    }
}

/// One tetrahedron's [`Tangent`] with its rest shape folded in, for the implicit solve's
/// products: `−K·u` is `V₀·U·T(Uᵀ·D_s·D_m⁻¹·V)·Vᵀ·D_m⁻ᵀ` with `D_s` the corners' displacements
/// from corner 0 and `T` the tangent in the frame, so this keeps `U`, `W = D_m⁻¹·V` and `V₀·T`,
/// and a product is four 3×3 products (`D_s·W`, `Uᵀ·…`, `U·…`, `…·Wᵀ`) instead of six and a
/// scaling. Its matrices are `Mat3A` (a column in one SIMD register). With both, a 20k-vertex
/// step of elements took 1.39× less time on one thread and 1.51× less on two (docs/integrator.md).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TetStiffness {
    u: Mat3A,
    w: Mat3A,
    /// `V₀·` the stretch block.
    stretch: Mat3A,
    /// `V₀·` the shears' weights: `T(d)_ij = a_ij·d_ij + b_ij·d_ji` off the diagonal (0 on it),
    /// with `a = (plus + minus)/2` and `b = (plus − minus)/2` of the pair's two eigenvalues.
    a: Mat3A,
    b: Mat3A,
}

impl TetStiffness {
    /// Folds tetrahedron `k`'s `D_m⁻¹` and [weight](Elements::weight) (its rest volume times its
    /// modulus) into `tangent`.
    #[must_use]
    pub fn new(elements: &Elements, k: usize, tangent: &Tangent) -> TetStiffness {
        let v0 = elements.weight(k);
        let mut a = [[0.0f32; 3]; 3]; // [column][row]
        let mut b = [[0.0f32; 3]; 3];
        for (pair, (i, j)) in [(1usize, 2usize), (0, 2), (0, 1)].into_iter().enumerate() {
            let [plus, minus] = tangent.shear[pair];
            let (sa, sb) = (0.5 * v0 * (plus + minus), 0.5 * v0 * (plus - minus));
            a[j][i] = sa;
            a[i][j] = sa;
            b[j][i] = sb;
            b[i][j] = sb;
        }
        TetStiffness {
            u: Mat3A::from(tangent.u),
            w: Mat3A::from(elements.dm_inv[k] * tangent.v),
            stretch: Mat3A::from(v0 * tangent.stretch),
            a: Mat3A::from_cols_array_2d(&a),
            b: Mat3A::from_cols_array_2d(&b),
        }
    }

    /// `V₀·δP·D_m⁻ᵀ` for the corners' displacements `u` (`δP` the [`Tangent`] applied to
    /// `D_s·D_m⁻¹`, to rounding): its columns are the forces' changes on corners 1..3 with the
    /// sign flipped (`−K·u`), corner 0 minus their sum ([`corner_of`]).
    #[must_use]
    pub fn product(&self, u: [Vec3; 4]) -> Mat3 {
        let u0 = Vec3A::from(u[0]);
        let ds = Mat3A::from_cols(Vec3A::from(u[1]) - u0, Vec3A::from(u[2]) - u0, Vec3A::from(u[3]) - u0);
        self.through(self.u.transpose() * (ds * self.w))
    }

    /// The [`product`](Self::product) of a unit displacement of corner `column` (1..=3) along
    /// `axis`: `D_s` is then that axis in the corner's column alone, so `Uᵀ·D_s·W` is the
    /// outer product of `U`'s row `axis` and `W`'s row `column − 1`, nine products instead of
    /// two matrices'.
    fn unit_product(&self, column: usize, axis: usize) -> Mat3 {
        let a = Vec3A::new(self.u.x_axis[axis], self.u.y_axis[axis], self.u.z_axis[axis]);
        let row = column - 1;
        let d = Mat3A::from_cols(a * self.w.x_axis[row], a * self.w.y_axis[row], a * self.w.z_axis[row]);
        self.through(d)
    }

    /// `U·T(d)·Wᵀ` for `d = Uᵀ·D_s·W`: the tangent applied in the singular frame, and back.
    fn through(&self, d: Mat3A) -> Mat3 {
        let dt = d.transpose();
        let diag = self.stretch * Vec3A::new(d.x_axis.x, d.y_axis.y, d.z_axis.z);
        let p = Mat3A::from_cols(
            self.a.x_axis * d.x_axis + self.b.x_axis * dt.x_axis + Vec3A::new(diag.x, 0.0, 0.0),
            self.a.y_axis * d.y_axis + self.b.y_axis * dt.y_axis + Vec3A::new(0.0, diag.y, 0.0),
            self.a.z_axis * d.z_axis + self.b.z_axis * dt.z_axis + Vec3A::new(0.0, 0.0, diag.z),
        );
        Mat3::from(self.u * p * self.w.transpose())
    }

    /// The sixteen blocks of `−K` between the tetrahedron's corners, `4·row + column`, each
    /// block's columns the [`product`](Self::product) of a unit displacement of its column
    /// corner; corner 0's are minus the others' (a translation moves nothing), so it takes
    /// nine products.
    #[must_use]
    pub fn blocks(&self) -> [Mat3; 16] {
        let mut out = [Mat3::ZERO; 16];
        self.blocks_into(&mut out);
        out
    }

    /// [`blocks`](Self::blocks) written into `out`.
    pub fn blocks_into(&self, out: &mut [Mat3; 16]) {
        for column in 1..4 {
            let cols = [0, 1, 2].map(|axis| self.unit_product(column, axis));
            for row in 0..4 {
                out[4 * row + column] = Mat3::from_cols(
                    corner_of(&cols[0], row),
                    corner_of(&cols[1], row),
                    corner_of(&cols[2], row),
                );
            }
        }
        for row in 0..4 {
            out[4 * row] = -(out[4 * row + 1] + out[4 * row + 2] + out[4 * row + 3]);
        }
    }
}

impl Elements {
    /// Every tetrahedron's [`TetStiffness`] at `pos`, projected.
    #[must_use]
    pub fn stiffnesses(&self, pos: &[Vec3]) -> Vec<TetStiffness> {
        self.stiffnesses_in(pos, &mut Vec::new())
    }

    /// [`stiffnesses`](Self::stiffnesses), each tetrahedron's decomposition started from its
    /// last one's frame and that frame kept for the next ([`Frames`]): a step's deformations
    /// differ little from the last's, so fewer rotations are left (the first call starts
    /// from the axes).
    #[cfg(test)]
    fn stiffnesses_warm(&self, pos: &[Vec3]) -> Vec<TetStiffness> {
        let mut cache = self.frames.0.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        self.stiffnesses_in(pos, &mut cache.frames)
    }

    /// The stiffnesses, each decomposition started from its frame in `frames` (from the axes
    /// where `frames` is not one a tetrahedron), and those frames replaced by the new ones.
    fn stiffnesses_in(&self, pos: &[Vec3], frames: &mut Vec<Mat3>) -> Vec<TetStiffness> {
        use rayon::prelude::*;
        let fresh = self.frames_ready(frames);
        frames
            .par_iter_mut()
            .enumerate()
            .with_min_len(1024)
            .map(|(k, frame)| self.stiffness_from(pos, k, frame, fresh))
            .collect()
    }

    /// `frames` made one a tetrahedron (the axes) where they are not; whether they were not.
    fn frames_ready(&self, frames: &mut Vec<Mat3>) -> bool {
        let fresh = frames.len() != self.tets.len();
        if fresh {
            *frames = vec![Mat3::IDENTITY; self.tets.len()];
        }
        fresh
    }

    /// Tetrahedron `k`'s stiffness at `pos`, its decomposition started from `frame` (from the
    /// axes where `fresh`), and `frame` replaced by its new one.
    fn stiffness_from(&self, pos: &[Vec3], k: usize, frame: &mut Mat3, fresh: bool) -> TetStiffness {
        let tangent = self.tangent_from(self.deformation(pos, k), true, (!fresh).then_some(*frame));
        *frame = tangent.v;
        TetStiffness::new(self, k, &tangent)
    }

    /// Tetrahedron `k`'s deformation gradient at `pos`.
    fn deformation(&self, pos: &[Vec3], k: usize) -> Mat3 {
        let p = self.tets[k].map(|v| pos[v as usize]);
        Mat3::from_cols(p[1] - p[0], p[2] - p[0], p[3] - p[0]) * self.dm_inv[k]
    }

    /// The material's projected stiffness at `F` ([`Tangent`]); `project = false` leaves it
    /// as it is (indefinite under compression), for checking against finite differences.
    #[must_use]
    pub fn tangent_at(&self, f: Mat3, project: bool) -> Tangent {
        self.tangent_from(f, project, None)
    }

    /// [`tangent_at`](Self::tangent_at), its decomposition started from the frame `start`
    /// ([`symmetric_eigen_from`]).
    fn tangent_from(&self, f: Mat3, project: bool, start: Option<Mat3>) -> Tangent {
        let (u, sigma, v) = rotation_svd(f, start);
        let (mu, lambda) = (self.mu, self.lambda);
        let j = sigma.x * sigma.y * sigma.z;
        let s = lambda * (j - self.alpha());
        // ∂J/∂σ_i: the product of the other two.
        let c = Vec3::new(sigma.y * sigma.z, sigma.x * sigma.z, sigma.x * sigma.y);
        let mut stretch = Mat3::from_cols(lambda * c.x * c, lambda * c.y * c, lambda * c.z * c)
            + Mat3::from_diagonal(Vec3::splat(mu));
        // ∂²J/∂σ_i∂σ_j: the third σ, off the diagonal.
        let cross_terms = Mat3::from_cols(
            Vec3::new(0.0, sigma.z, sigma.y),
            Vec3::new(sigma.z, 0.0, sigma.x),
            Vec3::new(sigma.y, sigma.x, 0.0),
        );
        stretch += s * cross_terms;
        let clamp = |x: f32| if project { x.max(0.0) } else { x };
        // Positive definite (its leading minors positive, Sylvester) is unchanged by the
        // projection: most tetrahedra of a body near rest, and then one eigen-decomposition
        // a tetrahedron instead of two.
        if project && !positive_definite(&stretch) {
            let (values, q) = symmetric_eigen(stretch);
            let l = Mat3::from_diagonal(Vec3::new(clamp(values.x), clamp(values.y), clamp(values.z)));
            stretch = q * l * q.transpose();
        }
        let shear = [sigma.x, sigma.y, sigma.z].map(|sk| [clamp(mu - s * sk), clamp(mu + s * sk)]);
        Tangent { u, v, stretch, shear }
    }
}

/// Whether the symmetric `a` is positive definite: its leading principal minors are positive.
fn positive_definite(a: &Mat3) -> bool {
    let (x, y) = (a.x_axis, a.y_axis);
    x.x > 0.0 && x.x * y.y - x.y * y.x > 0.0 && a.determinant() > 0.0
}

/// Corner `corner`'s share of a tetrahedron's `V₀·P·D_m⁻ᵀ`-shaped matrix `h`: its column
/// `corner − 1`, or minus their sum for corner 0.
#[must_use]
pub fn corner_of(h: &Mat3, corner: usize) -> Vec3 {
    match corner {
        0 => -(h.x_axis + h.y_axis + h.z_axis),
        1 => h.x_axis,
        2 => h.y_axis,
        _ => h.z_axis,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `P(F)` of the energy.
    fn stress(e: &Elements, f: Mat3) -> Mat3 {
        let j = f.determinant();
        let cof =
            Mat3::from_cols(f.y_axis.cross(f.z_axis), f.z_axis.cross(f.x_axis), f.x_axis.cross(f.y_axis));
        e.mu * f + (e.lambda * (j - e.alpha())) * cof
    }

    /// `A : B`.
    fn contract(a: Mat3, b: Mat3) -> f32 {
        a.to_cols_array().iter().zip(b.to_cols_array()).map(|(x, y)| x * y).sum()
    }

    fn one(nu: f64) -> Elements {
        let rest = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z];
        Elements::new(&rest, &[[0, 1, 2, 3]], 1.0, nu).unwrap()
    }

    /// Deformations: stretched, sheared, compressed, rotated, inverted.
    fn deformations() -> Vec<Mat3> {
        let rot = Mat3::from_axis_angle(Vec3::new(1.0, 2.0, 3.0).normalize(), 0.7);
        vec![
            Mat3::IDENTITY,
            Mat3::from_diagonal(Vec3::new(1.3, 0.9, 0.8)),
            rot * Mat3::from_cols(
                Vec3::new(1.1, 0.2, 0.0),
                Vec3::new(0.1, 0.7, 0.3),
                Vec3::new(-0.2, 0.1, 1.2),
            ),
            rot * Mat3::from_diagonal(Vec3::new(0.5, 0.6, 0.4)),
            Mat3::from_diagonal(Vec3::new(1.1, 0.9, -0.3)),
        ]
    }

    #[test]
    fn the_tangent_is_the_stress_derivative() {
        for nu in [0.3, 0.45] {
            let e = one(nu);
            for f in deformations() {
                let t = e.tangent_at(f, false);
                for k in 0..9 {
                    let mut df = [0.0f32; 9];
                    df[k] = 1.0;
                    let df = Mat3::from_cols_array(&df);
                    let eps = 1e-3;
                    let fd = (stress(&e, f + eps * df) - stress(&e, f - eps * df)) * (0.5 / eps);
                    let an = t.apply(df);
                    let scale = e.lambda.max(1.0) * (1.0 + f.abs().to_cols_array().iter().sum::<f32>());
                    assert!(
                        (fd - an).abs().to_cols_array().iter().all(|d| *d < 2e-3 * scale),
                        "ν {nu}, F {f}, direction {k}: {fd} against {an}"
                    );
                }
            }
        }
    }

    /// `V₀·δP·D_m⁻ᵀ` of tetrahedron `k` for its corners' displacements `u`, from the tangent
    /// and the rest shape as they are written: what [`TetStiffness::product`] folds.
    fn stiffness_product(e: &Elements, tangent: &Tangent, k: usize, u: [Vec3; 4]) -> Mat3 {
        let ds = Mat3::from_cols(u[1] - u[0], u[2] - u[0], u[3] - u[0]);
        let dp = tangent.apply(ds * e.dm_inv[k]);
        e.volume[k] * (dp * e.dm_inv[k].transpose())
    }

    #[test]
    fn the_folded_stiffness_is_the_tangent_through_the_rest_shape() {
        // A skewed tetrahedron, so that D_m⁻¹ is no rotation.
        let rest =
            [Vec3::ZERO, Vec3::new(1.3, 0.1, 0.0), Vec3::new(0.2, 0.9, 0.1), Vec3::new(-0.1, 0.3, 1.1)];
        let e = Elements::new(&rest, &[[0, 1, 2, 3]], 2.0, 0.45).unwrap();
        for f in deformations() {
            let t = e.tangent_at(f, true);
            let folded = TetStiffness::new(&e, 0, &t);
            for k in 0..12 {
                let u: [Vec3; 4] = std::array::from_fn(|c| {
                    Vec3::from_array(std::array::from_fn(|i| ((c * 3 + i + k * 5) as f32 * 0.77).sin()))
                });
                let (want, got) = (stiffness_product(&e, &t, 0, u), folded.product(u));
                let scale = want.abs().to_cols_array().into_iter().fold(1e-6, f32::max);
                let off = (want - got).abs().to_cols_array().into_iter().fold(0.0, f32::max);
                assert!(off <= 1e-5 * scale, "F {f}, case {k}: {want} against {got}");
            }
            // Every block between two corners, column by column, from unit displacements.
            let blocks = folded.blocks();
            for (pair, block) in blocks.iter().enumerate() {
                let (row, column) = (pair / 4, pair % 4);
                for (axis, e_axis) in [Vec3::X, Vec3::Y, Vec3::Z].into_iter().enumerate() {
                    let mut u = [Vec3::ZERO; 4];
                    u[column] = e_axis;
                    let want = corner_of(&stiffness_product(&e, &t, 0, u), row);
                    let got = block.col(axis);
                    let scale = 1e-5 * want.abs().max_element().max(1e-6);
                    assert!((want - got).abs().max_element() <= scale, "{pair}: {want} against {got}");
                }
            }
        }
    }

    #[test]
    fn the_assembled_stiffness_gives_every_tetrahedrons_product() {
        // A 3 × 3 × 3 lattice of unit cubes, deformed (stretched, sheared, one corner pushed
        // through its neighbour), at ν = 0.49: the assembled rows times a displacement equal
        // each vertex's sum over its tetrahedra of their own products.
        let mut rest = Vec::new();
        for z in 0..4 {
            for y in 0..4 {
                for x in 0..4 {
                    rest.push(Vec3::new(x as f32, y as f32, z as f32));
                }
            }
        }
        let e = Elements::new(&rest, &lattice_tets(&rest, 1.0), 1.0, 0.49).unwrap();
        let wobble = |i: usize, s: f32| {
            Vec3::new((s * i as f32).sin(), (1.7 * s * i as f32).cos(), (0.3 * i as f32).sin())
        };
        let mut pos: Vec<Vec3> = rest
            .iter()
            .enumerate()
            .map(|(i, p)| {
                Mat3::from_cols(Vec3::new(1.2, 0.1, 0.0), Vec3::new(0.0, 0.8, 0.2), Vec3::Z) * *p
                    + 0.15 * wobble(i, 1.3)
            })
            .collect();
        pos[21] = pos[22] + Vec3::new(0.3, 0.1, -0.2);
        let u: Vec<Vec3> = (0..rest.len()).map(|i| wobble(i, 2.9)).collect();
        let blocks = e.assemble(&pos);
        let stiffness = e.stiffnesses(&pos);
        let p = &e.pattern;
        for i in 0..rest.len() {
            let mut want = Vec3::ZERO;
            for &[k, c] in &e.adjacency[e.offsets[i] as usize..e.offsets[i + 1] as usize] {
                let h = stiffness[k as usize].product(e.tets[k as usize].map(|v| u[v as usize]));
                want += corner_of(&h, c as usize);
            }
            let mut got = Vec3::ZERO;
            for s in p.offsets[i] as usize..p.offsets[i + 1] as usize {
                got += blocks[s] * u[p.columns[s] as usize];
            }
            assert!(
                (want - got).length() <= 1e-4 * want.length().max(1.0),
                "vertex {i}: {want} against {got}"
            );
        }
        // A row couples a vertex to itself and the 14 vertices it shares a tetrahedron with.
        let inner = 21; // (1, 1, 1)
        assert_eq!(p.offsets[inner + 1] - p.offsets[inner], 15);
    }

    /// The eigen-decomposition of symmetric matrices as the stiffness meets them: near the
    /// identity (a tetrahedron at rest), with equal eigenvalues, diagonal, stretched and
    /// sheared, flat (a tetrahedron crushed to a plane), and in no particular form: the
    /// vectors are a right-handed orthonormal frame, `A·v = λ·v` to single precision, and the
    /// values come largest first.
    #[test]
    fn symmetric_matrices_decompose_into_their_eigenvalues_and_a_rotation() {
        let mut cases: Vec<Mat3> = deformations().into_iter().map(|f| f.transpose() * f).collect();
        cases.extend([
            Mat3::IDENTITY,
            Mat3::from_diagonal(Vec3::new(2.0, 2.0, 0.5)),
            Mat3::from_diagonal(Vec3::new(0.5, 3.0, 1.0)),
            Mat3::from_diagonal(Vec3::new(1.0, 1.0, 0.0)),
            Mat3::IDENTITY
                + 1e-6
                    * Mat3::from_cols(
                        Vec3::new(0.0, 1.0, 2.0),
                        Vec3::new(1.0, 0.0, 3.0),
                        Vec3::new(2.0, 3.0, 0.0),
                    ),
            Mat3::ZERO,
        ]);
        for k in 0..40 {
            let g = Mat3::from_cols_array(&std::array::from_fn(|i| ((i * 7 + k * 13) as f32 * 0.61).sin()));
            cases.push(g.transpose() * g);
        }
        for a in cases {
            let (values, v) = symmetric_eigen(a);
            let scale = a.abs().to_cols_array().into_iter().fold(1e-30, f32::max);
            let worst = |m: Mat3| m.abs().to_cols_array().into_iter().fold(0.0f32, f32::max);
            assert!(worst(v.transpose() * v - Mat3::IDENTITY) < 1e-5, "{a}: {v}");
            assert!((v.determinant() - 1.0).abs() < 1e-5, "{a}: {v}");
            assert!(values.x >= values.y && values.y >= values.z, "{a}: {values}");
            for (c, l) in [(v.x_axis, values.x), (v.y_axis, values.y), (v.z_axis, values.z)] {
                assert!((a * c - l * c).abs().max_element() <= 1e-5 * scale, "{a}: {l}, {c}");
            }
        }
    }

    /// Started from another frame (the last step's, a turned one, a frame that is not one, a
    /// NaN), the decomposition is the one started from the axes, to single precision; and an
    /// assembly warm-started from an earlier one gives the cold rows.
    #[test]
    fn a_decomposition_started_from_a_nearby_frame_is_the_same_decomposition() {
        let turn = Mat3::from_axis_angle(Vec3::new(1.0, 2.0, 0.5).normalize(), 0.7);
        for f in deformations() {
            let a = f.transpose() * f;
            let (values, v) = symmetric_eigen(a);
            let near = symmetric_eigen(
                (f + 0.01 * Mat3::from_diagonal(Vec3::new(1.0, -1.0, 0.5))).transpose()
                    * (f + 0.01 * Mat3::from_diagonal(Vec3::new(1.0, -1.0, 0.5))),
            )
            .1;
            let bad = Mat3::from_cols(Vec3::X, Vec3::X, Vec3::Z);
            for start in [
                Mat3::IDENTITY,
                v,
                near,
                turn,
                1.01 * turn,
                bad,
                Mat3::from_cols(Vec3::NAN, Vec3::Y, Vec3::Z),
            ] {
                let (w, u) = symmetric_eigen_from(a, Some(start));
                let scale = values.x.abs().max(1e-6);
                assert!((w - values).abs().max_element() <= 1e-5 * scale, "{f}: {w} against {values}");
                for (c, l) in [(u.x_axis, w.x), (u.y_axis, w.y), (u.z_axis, w.z)] {
                    assert!(
                        (a * c - l * c).abs().max_element() <= 1e-5 * scale,
                        "{f} from {start}: {l}, {c}"
                    );
                    assert!((c.length() - 1.0).abs() < 1e-5, "{f} from {start}: {c}");
                }
            }
        }
        let rest: Vec<Vec3> =
            (0..27).map(|i| Vec3::new((i % 3) as f32, ((i / 3) % 3) as f32, (i / 9) as f32)).collect();
        let e = Elements::new(&rest, &lattice_tets(&rest, 1.0), 1.0, 0.49).unwrap();
        let bent = |s: f32| -> Vec<Vec3> {
            rest.iter().map(|p| *p + s * Vec3::new((p.z * 1.3).sin(), 0.2 * p.x, (p.y * 0.7).cos())).collect()
        };
        let cold =
            |pos: &[Vec3]| e.stiffnesses(pos).iter().flat_map(TetStiffness::blocks).collect::<Vec<Mat3>>();
        let _ = e.assemble(&bent(0.1));
        let pos = bent(0.12);
        let (warm, want) = (e.stiffnesses_warm(&pos), cold(&pos));
        let got: Vec<Mat3> = warm.iter().flat_map(TetStiffness::blocks).collect();
        for (g, w) in got.iter().zip(&want) {
            let scale = w.abs().to_cols_array().into_iter().fold(1e-3, f32::max);
            let off = (*g - *w).abs().to_cols_array().into_iter().fold(0.0f32, f32::max);
            assert!(off <= 1e-4 * scale, "{g} against {w}");
        }
    }

    #[test]
    fn the_projected_tangent_is_positive_and_unchanged_where_it_was() {
        let e = one(0.45);
        for f in deformations() {
            let (t, raw) = (e.tangent_at(f, true), e.tangent_at(f, false));
            let mut negative_before = false;
            for k in 0..40 {
                // Pseudo-random directions.
                let df =
                    Mat3::from_cols_array(&std::array::from_fn(|i| ((i * 7 + k * 13) as f32 * 0.61).sin()));
                let q = contract(t.apply(df), df);
                let q_raw = contract(raw.apply(df), df);
                assert!(q >= -1e-4 * e.lambda, "F {f}: δF:A:δF = {q}");
                negative_before |= q_raw < 0.0;
            }
            if f == Mat3::IDENTITY {
                assert!(!negative_before, "at rest the tangent is already positive");
                let df = Mat3::from_cols_array(&[0.3, 0.1, -0.2, 0.4, 0.0, 0.5, 0.1, -0.3, 0.2]);
                let change =
                    (t.apply(df) - raw.apply(df)).abs().to_cols_array().into_iter().fold(0.0, f32::max);
                assert!(change < 1e-4, "projection changed it at rest by {change}");
            }
        }
    }
}
