//! The surface contact's search on the device (docs/contacts.md, "The search on the device"):
//! for each probing point, the nearest triangle of the partner's surface within the cutoff and
//! the push out of it, as [`crate::contact::SurfaceContact`] finds it on the CPU, to the bit.
//!
//! **The voxel model finds the candidates.** The partner's points are binned each step by the
//! core's passes ([`GpuCollision::record_binning`]: its grid follows them, its counting sort
//! lays them out by voxel slot), and each probe walks the 3×3×3 block of voxels about its own
//! to the triangles at the points binned there (`shaders/surface_search.wgsl`). A triangle within
//! the cutoff has a corner within the cutoff plus the surface's longest edge, which a pass
//! measures each step; the walk reaches that far, one voxel each way while the surface has not
//! stretched past the voxel it was binned for (the cutoff plus [`STRETCH`] times the longest
//! edge as given, the power of two above it: the core's grids take no other), and further where
//! it has (a filling implant's shell grows from its deflated start).
//!
//! **The explicit step on the device** ([`DeviceSurface`]): both sides' searches, then each
//! side's clearances, the inside test of doubtful hits and the way in kept for the next step,
//! and each vertex's force summed in the CPU's order (`shaders/surface_forces.wgsl`,
//! `shaders/surface_gather.wgsl`), with nothing read back; a lattice made from a surface shows
//! it the surface it carries (`shaders/surface_embed.wgsl`). The implicit integrator builds its
//! couplings from the same search ([`crate::gpu::implicit`]).
//! The search is held to the CPU's on the same positions (`tests/surface_search.rs`), and the
//! step to the CPU world's bits (`tests/simulation.rs`).

use bytemuck::{Pod, Zeroable};
use glam::{Vec3, Vec4};
use wgpu::{Buffer, BufferUsages};

use crate::contact::surface::edge_neighbours;
use crate::contact::{SurfaceHit, SurfacePenalty};
use crate::mesh::TriangleMesh;
use voxcollide::error::Error;
use voxcollide::gpu::kernel::{Kernel, Slot};
use voxcollide::gpu::{GpuContext, read_buffers, scoped};
use voxcollide::{Anchor, ContactParams, Direction, GpuCollision, Search};

/// A device buffer of `label` holding `contents`, for `usage`.
fn init(device: &wgpu::Device, label: &str, contents: &[u8], usage: BufferUsages) -> Buffer {
    use wgpu::util::DeviceExt as _;
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: Some(label), contents, usage })
}

pub use crate::contact::surface::STRETCH;

/// The search's passes (`main`, `longest_edge`) and the result they write; its shader is the
/// core's `common.wgsl` ([`voxcollide::gpu::shaders::COMMON`]) followed by this.
pub const SURFACE_SEARCH: &str = concat!(
    include_str!("../../shaders/surface_hit.wgsl"),
    include_str!("../../shaders/surface_search.wgsl")
);

/// Its uniform. Keep in sync with `Search` in `shaders/surface_search.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
struct GpuSearch {
    n_probes: u32,
    tri_at: u32,
    nbr_at: u32,
    off_at: u32,
    adj_at: u32,
    cutoff: f32,
    reach: f32,
    gap: f32,
    margin: f32,
    voxel: f32,
    n_triangles: u32,
    n_partner: u32,
}

/// The search's bindings (both its passes').
const SEARCH_SLOTS: [Slot; 10] = [
    Slot::Uniform,
    Slot::ReadWrite,
    Slot::Read,
    Slot::Read,
    Slot::Uniform,
    Slot::Read,
    Slot::Read,
    Slot::Read,
    Slot::ReadWrite,
    Slot::ReadWrite,
];

/// One probe's result. Keep in sync with `SurfaceHit` in `shaders/surface_hit.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
struct GpuHit {
    normal: [f32; 4],
    weights: [f32; 4],
    entry: [f32; 4],
    triangle: u32,
    found: u32,
    clear: f32,
    _pad: u32,
}

/// The search of one side of a surface contact (one body's points probing the other's
/// surface) on the device.
#[derive(Debug)]
pub struct SurfaceSearch {
    binning: GpuCollision,
    kernel: Kernel,
    /// The pass measuring the surface's longest edge first (`longest_edge`).
    edge_kernel: Kernel,
    /// Its answer (`edge` in the shader).
    edge: Buffer,
    uniform: Buffer,
    topology: Buffer,
    hits: Buffer,
    n_probes: u32,
    n_partner: u32,
    /// The partner's triangles, as `topology` begins.
    corners: Vec<[u32; 3]>,
    /// The bind groups (the search's, the longest edge's), and the buffers they were made
    /// over (the probes', the partner's, and the binning's starts).
    group: Option<([Buffer; 3], [wgpu::BindGroup; 2])>,
}

impl SurfaceSearch {
    /// A search of `n_probes` points against the surface `mesh` over the partner's points as
    /// they are now (`partner`), with `penalty`'s cutoff.
    ///
    /// # Errors
    /// [`Error::Invalid`] for a bad `penalty` or an empty surface; the grid's and the binning's
    /// errors; [`Error::Gpu`] when the device refuses the pipeline or a buffer.
    pub fn new(
        ctx: &GpuContext,
        penalty: SurfacePenalty,
        mesh: &TriangleMesh,
        partner: &[Vec3],
        n_probes: usize,
    ) -> Result<SurfaceSearch, Error> {
        penalty.validate()?;
        let empty = |what: &'static str| Error::Invalid {
            what,
            value: "0".into(),
            rule: "the surface contact's search on the device needs at least one".into(),
        };
        if mesh.triangles.is_empty() || partner.is_empty() {
            return Err(empty("triangle"));
        }
        if n_probes == 0 {
            return Err(empty("probing point"));
        }
        let cutoff = penalty.reach.max(penalty.gap + penalty.margin);
        let grid = crate::contact::surface::search_grid(cutoff, mesh, partner, None)?
            .ok_or_else(|| empty("finite partner point"))?;
        let voxel = grid.voxel_size();
        let params = ContactParams {
            magnitude: 1.0,
            search: Search::Voxel,
            direction: Direction::Pairwise,
            anchor: Anchor::FollowA,
        };
        let binning = GpuCollision::new(ctx, grid, params)?;
        let device = ctx.device();
        let (offsets, adjacency) = mesh.triangles_at(partner.len());
        let mut topology: Vec<u32> = mesh.triangles.iter().flatten().copied().collect();
        let nbr_at = topology.len() as u32;
        topology.extend(edge_neighbours(mesh).iter().flatten());
        let off_at = topology.len() as u32;
        topology.extend(&offsets);
        let adj_at = topology.len() as u32;
        topology.extend(&adjacency);
        let search = GpuSearch {
            n_probes: n_probes as u32,
            tri_at: 0,
            nbr_at,
            off_at,
            adj_at,
            cutoff,
            reach: penalty.reach,
            gap: penalty.gap,
            margin: penalty.margin,
            voxel,
            n_triangles: mesh.triangles.len() as u32,
            n_partner: partner.len() as u32,
        };
        let source = [voxcollide::gpu::shaders::COMMON, SURFACE_SEARCH].concat();
        scoped(device, || {
            let storage = BufferUsages::STORAGE | BufferUsages::COPY_SRC | BufferUsages::COPY_DST;
            SurfaceSearch {
                binning,
                kernel: Kernel::new(device, "sim surface search", &source, &SEARCH_SLOTS),
                edge_kernel: Kernel::entry(
                    device,
                    "sim surface longest edge",
                    &source,
                    &SEARCH_SLOTS,
                    "longest_edge",
                ),
                edge: device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("sim surface longest edge"),
                    size: 16,
                    usage: storage,
                    mapped_at_creation: false,
                }),
                uniform: init(
                    device,
                    "sim surface search",
                    bytemuck::bytes_of(&search),
                    BufferUsages::UNIFORM | BufferUsages::COPY_DST,
                ),
                topology: init(device, "sim surface topology", bytemuck::cast_slice(&topology), storage),
                hits: init(
                    device,
                    "sim surface hits",
                    bytemuck::cast_slice(&vec![GpuHit::default(); n_probes]),
                    storage,
                ),
                n_probes: n_probes as u32,
                n_partner: partner.len() as u32,
                corners: mesh.triangles.clone(),
                group: None,
            }
        })
    }

    /// Records one search into `encoder`: the partner's points in `partner` (`vec4<f32>` each)
    /// binned, then each of the probing points in `probes` searched; the hits are in
    /// [`hits_buffer`](Self::hits_buffer) once the app has submitted it.
    ///
    /// # Errors
    /// The binning's input errors ([`GpuCollision::record_binning`]); [`Error::BufferTooSmall`]
    /// for a probe buffer that cannot hold the probes; [`Error::Gpu`] when the device refuses
    /// the bind group.
    pub fn record(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        probes: &Buffer,
        partner: &Buffer,
    ) -> Result<(), Error> {
        let needed = 16 * u64::from(self.n_probes);
        if probes.size() < needed {
            return Err(Error::BufferTooSmall {
                body: voxcollide::Body::B,
                len: self.n_probes,
                size: probes.size(),
                needed,
            });
        }
        self.binning.record_binning(encoder, partner, self.n_partner)?;
        let b = &self.binning;
        let (Some(params), Some(state), Some(starts), Some(sorted)) =
            (b.params_buffer(), b.state_buffer(), b.slot_starts_buffer(), b.sorted_buffer())
        else {
            unreachable!("the binning was just recorded")
        };
        let keys = [probes.clone(), partner.clone(), starts.clone()];
        if self.group.as_ref().is_none_or(|(k, _)| *k != keys) {
            let device = self.binning.context().device().clone();
            let buffers = [
                params,
                state,
                starts,
                sorted,
                &self.uniform,
                probes,
                partner,
                &self.topology,
                &self.hits,
                &self.edge,
            ];
            let group = scoped(&device, || {
                [self.kernel.bind(&device, &buffers), self.edge_kernel.bind(&device, &buffers)]
            })?;
            self.group = Some((keys, group));
        }
        let Some((_, [group, edge_group])) = self.group.as_ref() else {
            unreachable!("the bind group was just made")
        };
        let max = self.binning.context().device().limits().max_compute_workgroups_per_dimension;
        encoder.clear_buffer(&self.edge, 0, Some(4));
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("sim surface search"),
            timestamp_writes: None,
        });
        self.edge_kernel.dispatch(&mut pass, edge_group, self.corners.len() as u32, max);
        self.kernel.dispatch(&mut pass, group, self.n_probes, max);
        Ok(())
    }

    /// Each probe's result after a submitted search (`SurfaceHit` in
    /// `shaders/surface_search.wgsl`, 64 bytes a probe).
    #[must_use]
    pub fn hits_buffer(&self) -> &Buffer {
        &self.hits
    }

    /// The way each probe was pushed out at the last step (zero: it was not inside), which the
    /// next search keeps to ([`crate::contact::SurfaceContact`]'s "out the way it came in").
    pub fn set_entry(&self, queue: &wgpu::Queue, entry: &[Vec3]) {
        let hits: Vec<GpuHit> = (0..self.n_probes as usize)
            .map(|k| GpuHit {
                entry: entry.get(k).copied().unwrap_or(Vec3::ZERO).extend(0.0).to_array(),
                ..GpuHit::default()
            })
            .collect();
        queue.write_buffer(&self.hits, 0, bytemuck::cast_slice(&hits));
    }

    /// Reads back each probe's push (`None`: not within the cutoff, or not pushed), after the
    /// app has submitted a search. Blocks until the device is done.
    ///
    /// # Errors
    /// [`Error::Simulation`] once the partner has grown past the grid that bins it (twice its
    /// widest as set up, every way): a push there could be missed; [`Error::Gpu`] / [`Error::DeviceLost`]
    /// when the readback fails.
    pub fn read_hits(&self) -> Result<Vec<Option<SurfaceHit>>, Error> {
        let bytes = read_buffers(
            self.binning.context(),
            &[(&self.hits, 64 * u64::from(self.n_probes)), (&self.edge, 16)],
        )?;
        self.check_binned(&bytes[1])?;
        let hits: &[GpuHit] = bytemuck::cast_slice(&bytes[0]);
        Ok(hits
            .iter()
            .map(|h| {
                (h.found == 1).then(|| SurfaceHit {
                    triangle: h.triangle,
                    weights: [h.weights[0], h.weights[1], h.weights[2]],
                    normal: Vec4::from_array(h.normal).truncate(),
                    depth: h.normal[3],
                })
            })
            .collect())
    }

    /// [`Error::Simulation`] where a step's binning left a point of the partner out since the
    /// search was set up (`edge`'s second word as read back: the partner grew past the grid
    /// that bins it, and a contact there could be missed).
    fn check_binned(&self, edge: &[u8]) -> Result<(), Error> {
        let flags: [u32; 4] = bytemuck::pod_read_unaligned(&edge[..16]);
        if flags[1] == 0 {
            return Ok(());
        }
        let grid = self.binning.grid();
        Err(Error::Simulation {
            step: 0,
            message: format!(
                "the surface contact on the device: the partner's surface grew past the grid its search bins it in ({:?} voxels of {}, twice its widest as set up), and a contact there could be missed; run it with --backend cpu",
                grid.dims().to_array(),
                grid.voxel_size()
            ),
        })
    }

    /// The buffer of the partner's surface (its triangles' corners from word 0), as the passes
    /// after the search read it.
    pub(crate) fn topology_buffer(&self) -> &Buffer {
        &self.topology
    }

    /// The partner's triangles.
    pub(crate) fn corners(&self) -> &[[u32; 3]] {
        &self.corners
    }

    /// The voxel of the binning: the power of two at or above the cutoff plus [`STRETCH`] times
    /// the longest edge.
    #[must_use]
    pub fn voxel_size(&self) -> f32 {
        self.binning.grid().voxel_size()
    }
}

/// The passes after the search (`shaders/surface_forces.wgsl`), composed with
/// `sim_common.wgsl`; entry points `partner_moved`, `age`, `confirm`, `count`, `scan`,
/// `scatter`.
pub const SURFACE_FORCES: &str = concat!(
    include_str!("../../shaders/sim_common.wgsl"),
    include_str!("../../shaders/surface_hit.wgsl"),
    include_str!("../../shaders/surface_forces.wgsl")
);
/// A lattice's points where it carries a surface (`shaders/surface_embed.wgsl`), composed with
/// `sim_common.wgsl`.
pub const SURFACE_EMBED: &str = concat!(
    include_str!("../../shaders/sim_common.wgsl"),
    include_str!("../../shaders/carried.wgsl"),
    include_str!("../../shaders/surface_embed.wgsl")
);
/// The forces on one body's vertices (`shaders/surface_gather.wgsl`), composed with
/// `sim_common.wgsl`.
pub const SURFACE_GATHER: &str = concat!(
    include_str!("../../shaders/sim_common.wgsl"),
    include_str!("../../shaders/surface_hit.wgsl"),
    include_str!("../../shaders/surface_gather.wgsl")
);
/// The entry points of [`SURFACE_FORCES`], in the order a side runs them (the search between
/// `age` and `confirm`).
pub const SURFACE_FORCES_ENTRIES: [&str; 6] = ["partner_moved", "age", "confirm", "count", "scan", "scatter"];

/// A side's uniform. Keep in sync with `Side` in `shaders/surface_forces.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
struct GpuSide {
    n_probes: u32,
    n_partner: u32,
    first: u32,
    moved_at: u32,
    inside_at: u32,
    count_at: u32,
    cursor_at: u32,
    keys_at: u32,
    stiffness: f32,
    gap: f32,
    reach: f32,
    n_triangles: u32,
}

/// A body's gather uniform. Keep in sync with `Gather` in `shaders/surface_gather.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
struct GpuGather {
    n: u32,
    own_first: u32,
    starts_at: u32,
    keys_at: u32,
    stiffness: f32,
    carried: u32,
    _pad: [u32; 2],
}

/// A carried point. Keep in sync with `Carried` in `shaders/carried.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
struct GpuCarried {
    rest: [f32; 4],
    corners: [u32; 8],
    weights: [f32; 8],
}

/// A lattice that carries the surface it shows its contacts, on the device: the pass that
/// writes its points (its vertices, then the carried surface's) into `view` each step.
#[derive(Debug)]
struct Carried {
    uniform: Buffer,
    rest: Buffer,
    carried: Buffer,
    view: Buffer,
    /// The bind group, and the position buffer it was made over.
    group: Option<(Buffer, wgpu::BindGroup)>,
    points: u32,
}

/// A body as its surface contact sees it (the CPU's `View` in `contact/surface.rs`): its points
/// (its vertices, then the points of the surface it carries, if any) and the surface it shows
/// over them.
struct Shown {
    pos: Vec<Vec3>,
    mesh: TriangleMesh,
}

impl Shown {
    fn of(body: &crate::body::MassSpring) -> Shown {
        Shown {
            pos: body.with_carried(&body.pos),
            mesh: body.carried_mesh().unwrap_or_else(|| body.surface.clone()),
        }
    }
}

/// Point `p` of `body`'s points (see [`Shown`]) as its vertices and their weights: the CPU's
/// `View::stencil`.
fn stencil(body: &crate::body::MassSpring, p: u32) -> Vec<(u32, f32)> {
    match body.carried() {
        Some(e) if p as usize >= body.len() => {
            let k = p as usize - body.len();
            e.corners[k]
                .iter()
                .zip(&e.weights[k])
                .filter(|(c, _)| **c != u32::MAX)
                .map(|(c, w)| (*c, *w))
                .collect()
        }
        _ => vec![(p, 1.0)],
    }
}

/// What [`DeviceSurface::read`] reads back: the forces on `a` and on `b`, and the vertices of
/// `b` in contact.
pub type ReadBack = (Vec<Vec3>, Vec<Vec3>, Vec<u32>);

/// One side of a [`DeviceSurface`] as the implicit solve's couplings are built from it
/// ([`DeviceSurface::side_lists`]).
pub(crate) struct SideLists<'a> {
    /// The probes: every point of the probing body (its vertices, then those of the surface it
    /// carries, if any).
    pub n_probes: u32,
    /// The probing body's and the partner's: their vertices, and where they carry a surface,
    /// their carried points (`Carried` in `shaders/surface_embed.wgsl`).
    pub probe: (u32, Option<&'a Buffer>),
    pub partner: (u32, Option<&'a Buffer>),
    /// The partner's points per vertex (the gather's `points`: placeholder where it carries
    /// none).
    pub partner_points: &'a Buffer,
    /// Each probe's `SurfaceHit` (`shaders/surface_hit.wgsl`).
    pub hits: &'a Buffer,
    /// The partner's triangles, three corners each.
    pub topology: &'a Buffer,
    /// Per partner vertex, where its listed hits start (from `starts_at`, `n_partner + 1` of
    /// them), and their keys `3·probe + corner` (from `keys_at`), as `u32`s.
    pub scratch: &'a Buffer,
    pub starts_at: u32,
    pub keys_at: u32,
    /// The contact's stiffness.
    pub stiffness: f32,
}

/// One side of a [`DeviceSurface`]: its search and what the passes after it keep.
#[derive(Debug)]
struct DeviceSide {
    search: SurfaceSearch,
    side: GpuSide,
    uniform: Buffer,
    /// The probes' positions at the last step, then the partner's.
    prev: Buffer,
    /// See `scratch` in `shaders/surface_forces.wgsl`.
    scratch: Buffer,
    /// Per pass of [`SURFACE_FORCES_ENTRIES`], its bind group, and the position buffers they
    /// were made over.
    group: Option<([Buffer; 2], Vec<wgpu::BindGroup>)>,
}

/// The pipelines of a [`DeviceSurface`].
#[derive(Debug)]
struct SurfaceKernels {
    /// [`SURFACE_FORCES_ENTRIES`]'s, in order.
    side: Vec<Kernel>,
    gather: Kernel,
    embed: Kernel,
}

/// A surface contact stepped wholly on the device: both sides'
/// searches ([`SurfaceSearch`]), the passes after them, and each body's forces, in buffers the
/// `forces` pass reads, with nothing read back. A lattice that carries the surface it was made
/// from ([`crate::body::Embedding`]) shows the contact that surface, as on the CPU: its points
/// are its vertices, then the carried surface's, written each step (`shaders/surface_embed.wgsl`),
/// and a force on a carried point is shared by its cell's corners in their weights. The same forces as
/// [`SurfaceContact::step`](crate::contact::SurfaceContact::step), to the bit, but where the
/// inside test of a doubtful hit lands within rounding of one half (the device sums its winding
/// number in `f32` over every triangle, the CPU in `f64` through a hierarchy).
#[derive(Debug)]
pub struct DeviceSurface {
    /// `b`'s points probing `a`'s surface, then `a`'s probing `b`'s.
    sides: [DeviceSide; 2],
    kernels: SurfaceKernels,
    /// Per body (`a`, `b`): the gather's uniform, its free flags, its forces, and its points
    /// (where it carries a surface; a placeholder otherwise).
    gather: [(Buffer, Buffer, Buffer, Buffer); 2],
    gather_groups: Option<[wgpu::BindGroup; 2]>,
    /// Per body (`a`, `b`): its vertices, and where it carries a surface, the pass that writes
    /// its points.
    bodies: [(u32, Option<Carried>); 2],
    /// Per point of `b`, its vertices and weights (for the vertices of `b` in contact).
    b_stencils: Vec<Vec<(u32, f32)>>,
    steps: u64,
    max_per_dim: u32,
    /// What the last read found.
    stats: std::cell::Cell<crate::contact::SurfaceStats>,
}

impl DeviceSurface {
    /// The contact `penalty` between bodies `a` and `b` as they are now.
    ///
    /// # Errors
    /// [`Error::Invalid`] for an empty surface or a bad `penalty`; [`Error::Gpu`] when the
    /// device refuses a pipeline or a buffer.
    pub fn new(
        ctx: &GpuContext,
        penalty: SurfacePenalty,
        a: &crate::body::MassSpring,
        b: &crate::body::MassSpring,
    ) -> Result<DeviceSurface, Error> {
        let device = ctx.device();
        let storage = BufferUsages::STORAGE | BufferUsages::COPY_SRC | BufferUsages::COPY_DST;
        let (shown_a, shown_b) = (Shown::of(a), Shown::of(b));
        let side = |probing: &Shown, partner: &Shown| -> Result<DeviceSide, Error> {
            let search = SurfaceSearch::new(ctx, penalty, &partner.mesh, &partner.pos, probing.pos.len())?;
            let (np, nq) = (probing.pos.len() as u32, partner.pos.len() as u32);
            let count_at = 1 + 2 * np;
            let cursor_at = count_at + nq + 1;
            let keys_at = cursor_at + nq;
            let side = GpuSide {
                n_probes: np,
                n_partner: nq,
                first: 1,
                moved_at: 1,
                inside_at: 1 + np,
                count_at,
                cursor_at,
                keys_at,
                stiffness: penalty.stiffness,
                gap: penalty.gap,
                reach: penalty.reach,
                n_triangles: partner.mesh.triangles.len() as u32,
            };
            scoped(device, || {
                let zeros = |label: &str, bytes: u64| {
                    device.create_buffer(&wgpu::BufferDescriptor {
                        label: Some(label),
                        size: bytes.max(16),
                        usage: storage,
                        mapped_at_creation: false,
                    })
                };
                DeviceSide {
                    search,
                    side,
                    uniform: init(
                        device,
                        "sim surface side",
                        bytemuck::bytes_of(&side),
                        BufferUsages::UNIFORM | BufferUsages::COPY_DST,
                    ),
                    prev: zeros("sim surface prev", 16 * u64::from(np + nq)),
                    scratch: zeros("sim surface scratch", 4 * u64::from(keys_at + 3 * np)),
                    group: None,
                }
            })
        };
        let sides = [side(&shown_b, &shown_a)?, side(&shown_a, &shown_b)?];
        let kernels = scoped(device, || {
            let side_slots = [
                Slot::Uniform,
                Slot::Read,
                Slot::Read,
                Slot::ReadWrite,
                Slot::ReadWrite,
                Slot::ReadWrite,
                Slot::Read,
            ];
            SurfaceKernels {
                side: SURFACE_FORCES_ENTRIES
                    .iter()
                    .map(|entry| {
                        Kernel::entry(device, "sim surface forces", SURFACE_FORCES, &side_slots, entry)
                    })
                    .collect(),
                gather: Kernel::new(
                    device,
                    "sim surface gather",
                    SURFACE_GATHER,
                    &[
                        Slot::Uniform,
                        Slot::Read,
                        Slot::Read,
                        Slot::Read,
                        Slot::Read,
                        Slot::ReadWrite,
                        Slot::Read,
                    ],
                ),
                embed: Kernel::new(
                    device,
                    "sim surface embed",
                    SURFACE_EMBED,
                    &[Slot::Uniform, Slot::Read, Slot::Read, Slot::Read, Slot::ReadWrite],
                ),
            }
        })?;
        // Body a's reactions are the first side's (b probing a), b's the second's.
        let gather = |k: usize, body: &crate::body::MassSpring| {
            let other = &sides[k].side;
            let uniform = GpuGather {
                n: body.len() as u32,
                own_first: u32::from(k == 1),
                starts_at: other.count_at,
                keys_at: other.keys_at,
                stiffness: penalty.stiffness,
                carried: u32::from(body.carried().is_some()),
                _pad: [0; 2],
            };
            let free: Vec<u32> = body.mode.iter().map(|m| u32::from(*m == crate::body::Mode::Free)).collect();
            // Per vertex, the points whose stencils hold it, in point order: itself, then the
            // carried surface's points in its cells.
            let points: Vec<u32> = match body.carried() {
                Some(e) => {
                    let n = body.len();
                    let mut lists: Vec<Vec<(u32, f32)>> = (0..n).map(|v| vec![(v as u32, 1.0)]).collect();
                    for (k, (c, w)) in e.corners.iter().zip(&e.weights).enumerate() {
                        for (c, w) in c.iter().zip(w).filter(|(c, _)| **c != u32::MAX) {
                            lists[*c as usize].push(((n + k) as u32, *w));
                        }
                    }
                    // (The gather's rounds take each point once: a cell's kept corners are
                    // distinct.)
                    debug_assert!(lists.iter().all(|l| l.windows(2).all(|p| p[0].0 < p[1].0)));
                    let mut offsets = Vec::with_capacity(n + 1);
                    let mut pairs = Vec::new();
                    for l in &lists {
                        offsets.push((pairs.len() / 2) as u32);
                        pairs.extend(l.iter().flat_map(|(p, w)| [*p, w.to_bits()]));
                    }
                    offsets.push((pairs.len() / 2) as u32);
                    offsets.extend(pairs);
                    offsets
                }
                None => vec![0; 4],
            };
            scoped(device, || {
                (
                    init(device, "sim surface gather", bytemuck::bytes_of(&uniform), BufferUsages::UNIFORM),
                    init(device, "sim surface free", bytemuck::cast_slice(&free), BufferUsages::STORAGE),
                    init(
                        device,
                        "sim surface contact forces",
                        bytemuck::cast_slice(&vec![[0f32; 4]; body.len()]),
                        storage,
                    ),
                    init(device, "sim surface points", bytemuck::cast_slice(&points), BufferUsages::STORAGE),
                )
            })
        };
        let gather = [gather(0, a)?, gather(1, b)?];
        let carried = |body: &crate::body::MassSpring, shown: &Shown| -> Result<Option<Carried>, Error> {
            let Some(e) = body.carried() else { return Ok(None) };
            let (n, m) = (body.len() as u32, e.rest.len() as u32);
            let points: Vec<GpuCarried> = e
                .rest
                .iter()
                .zip(&e.corners)
                .zip(&e.weights)
                .map(|((r, c), w)| GpuCarried { rest: r.extend(0.0).to_array(), corners: *c, weights: *w })
                .collect();
            let rest: Vec<Vec4> = body.rest_pos.iter().map(|r| r.extend(0.0)).collect();
            let view: Vec<Vec4> = shown.pos.iter().map(|p| p.extend(0.0)).collect();
            scoped(device, || Carried {
                uniform: init(
                    device,
                    "sim surface embed",
                    bytemuck::cast_slice(&[n, m, 0, 0]),
                    BufferUsages::UNIFORM,
                ),
                rest: init(device, "sim surface rest", bytemuck::cast_slice(&rest), BufferUsages::STORAGE),
                carried: init(
                    device,
                    "sim surface carried",
                    bytemuck::cast_slice(&points),
                    BufferUsages::STORAGE,
                ),
                view: init(device, "sim surface points", bytemuck::cast_slice(&view), storage),
                group: None,
                points: n + m,
            })
            .map(Some)
        };
        let bodies = [(a.len() as u32, carried(a, &shown_a)?), (b.len() as u32, carried(b, &shown_b)?)];
        let b_stencils = (0..shown_b.pos.len() as u32).map(|p| stencil(b, p)).collect();
        Ok(DeviceSurface {
            sides,
            kernels,
            gather,
            gather_groups: None,
            bodies,
            b_stencils,
            steps: 0,
            max_per_dim: device.limits().max_compute_workgroups_per_dimension,
            stats: std::cell::Cell::default(),
        })
    }

    /// Records one step of the contact into `encoder` over the bodies' position buffers (`a`
    /// then `b`, `vec4<f32>` each); the forces are in [`force_buffer`](Self::force_buffer) once
    /// it is submitted.
    ///
    /// # Errors
    /// The searches' recording errors; [`Error::Gpu`] when the device refuses a bind group.
    pub fn record(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        queue: &wgpu::Queue,
        a: &Buffer,
        b: &Buffer,
    ) -> Result<(), Error> {
        let device = self.sides[0].search.binning.context().device().clone();
        let first = self.steps == 0;
        // A lattice that carries a surface: its points first.
        for ((_, carried), pos) in self.bodies.iter_mut().zip([a, b]) {
            let Some(c) = carried else { continue };
            if c.group.as_ref().is_none_or(|(k, _)| k != pos) {
                let group = scoped(&device, || {
                    self.kernels.embed.bind(&device, &[&c.uniform, pos, &c.rest, &c.carried, &c.view])
                })?;
                c.group = Some((pos.clone(), group));
            }
            let Some((_, group)) = c.group.as_ref() else { unreachable!("bound above") };
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("sim surface embed"),
                timestamp_writes: None,
            });
            self.kernels.embed.dispatch(&mut pass, group, c.points, self.max_per_dim);
        }
        let view = |k: usize, pos: &Buffer| -> Buffer {
            self.bodies[k].1.as_ref().map_or_else(|| pos.clone(), |c| c.view.clone())
        };
        let (a, b) = (&view(0, a), &view(1, b));
        for (s, side) in self.sides.iter_mut().enumerate() {
            let (probes, partner) = if s == 0 { (b, a) } else { (a, b) };
            if side.side.first != u32::from(first) {
                side.side.first = u32::from(first);
                queue.write_buffer(&side.uniform, 0, bytemuck::bytes_of(&side.side));
            }
            let keys = [probes.clone(), partner.clone()];
            if side.group.as_ref().is_none_or(|(k, _)| *k != keys) {
                let buffers = [
                    &side.uniform,
                    probes,
                    partner,
                    &side.prev,
                    &side.scratch,
                    side.search.hits_buffer(),
                    side.search.topology_buffer(),
                ];
                let group = scoped(&device, || {
                    self.kernels.side.iter().map(|k| k.bind(&device, &buffers)).collect()
                })?;
                side.group = Some((keys, group));
                self.gather_groups = None;
            }
            let Some((_, group)) = side.group.as_ref() else { unreachable!("bound above") };
            let g = &side.side;
            encoder.clear_buffer(&side.scratch, 0, Some(4));
            encoder.clear_buffer(
                &side.scratch,
                4 * u64::from(g.count_at),
                Some(4 * u64::from(g.keys_at - g.count_at)),
            );
            {
                let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("sim surface age"),
                    timestamp_writes: None,
                });
                self.kernels.side[0].dispatch(&mut pass, &group[0], g.n_partner, self.max_per_dim);
                self.kernels.side[1].dispatch(&mut pass, &group[1], g.n_probes, self.max_per_dim);
            }
            side.search.record(encoder, probes, partner)?;
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("sim surface confirm"),
                timestamp_writes: None,
            });
            self.kernels.side[2].dispatch(&mut pass, &group[2], g.n_probes, self.max_per_dim);
            self.kernels.side[3].dispatch(&mut pass, &group[3], g.n_probes, self.max_per_dim);
            self.kernels.side[4].dispatch_one(&mut pass, &group[4]);
            self.kernels.side[5].dispatch(&mut pass, &group[5], g.n_probes, self.max_per_dim);
        }
        if self.gather_groups.is_none() {
            let [s0, s1] = &self.sides;
            let bind = |k: usize| {
                let (own, other) = if k == 0 { (s1, s0) } else { (s0, s1) };
                let (uniform, free, force, points) = &self.gather[k];
                self.kernels.gather.bind(
                    &device,
                    &[
                        uniform,
                        own.search.hits_buffer(),
                        other.search.hits_buffer(),
                        &other.scratch,
                        free,
                        force,
                        points,
                    ],
                )
            };
            self.gather_groups = Some(scoped(&device, || [bind(0), bind(1)])?);
        }
        let Some(groups) = self.gather_groups.as_ref() else { unreachable!("bound above") };
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("sim surface gather"),
            timestamp_writes: None,
        });
        for (group, (n, _)) in groups.iter().zip(&self.bodies) {
            self.kernels.gather.dispatch(&mut pass, group, *n, self.max_per_dim);
        }
        drop(pass);
        self.steps += 1;
        Ok(())
    }

    /// Side `s` (0: `b`'s points probing `a`'s surface; 1: `a`'s probing `b`'s) after a
    /// recorded step, as the implicit solve's couplings are built from it on the device
    /// ([`crate::gpu::implicit`]): each probe's hit, the partner's triangles, and the lists of
    /// the hits on each partner vertex's triangles.
    pub(crate) fn side_lists(&self, s: usize) -> SideLists<'_> {
        let side = &self.sides[s];
        // Side 0: b's points probing a's surface; side 1: a's probing b's.
        let (probe, partner) = if s == 0 { (1, 0) } else { (0, 1) };
        let body = |k: usize| (self.bodies[k].0, self.bodies[k].1.as_ref().map(|c| &c.carried));
        SideLists {
            n_probes: side.side.n_probes,
            probe: body(probe),
            partner: body(partner),
            partner_points: &self.gather[partner].3,
            hits: side.search.hits_buffer(),
            topology: side.search.topology_buffer(),
            scratch: &side.scratch,
            starts_at: side.side.count_at,
            keys_at: side.side.keys_at,
            stiffness: side.side.stiffness,
        }
    }

    /// The forces on `a` (`as_a`) or on `b`, one `vec4<f32>` per vertex (w 0).
    #[must_use]
    pub fn force_buffer(&self, as_a: bool) -> &Buffer {
        &self.gather[usize::from(!as_a)].2
    }

    /// The last step's forces on `a` and `b`, and the vertices of `b` in contact (ascending, as
    /// [`SurfaceForces::touching_b`](crate::contact::SurfaceForces) gives them), read back;
    /// what it found is kept for [`stats`](Self::stats). Blocks until the device is done.
    ///
    /// # Errors
    /// [`Error::Gpu`] / [`Error::DeviceLost`] when the readback fails.
    pub fn read(&self) -> Result<ReadBack, Error> {
        let ctx = self.sides[0].search.binning.context();
        let sizes = [self.bodies[0].0, self.bodies[1].0];
        let points = [self.sides[1].side.n_probes, self.sides[0].side.n_probes];
        let bytes = read_buffers(
            ctx,
            &[
                (&self.gather[0].2, 16 * u64::from(sizes[0])),
                (&self.gather[1].2, 16 * u64::from(sizes[1])),
                (self.sides[0].search.hits_buffer(), 64 * u64::from(points[1])),
                (self.sides[1].search.hits_buffer(), 64 * u64::from(points[0])),
                (&self.sides[0].search.edge, 16),
                (&self.sides[1].search.edge, 16),
            ],
        )?;
        for (side, edge) in self.sides.iter().zip(&bytes[4..]) {
            side.search.check_binned(edge).map_err(|e| match e {
                Error::Simulation { message, .. } => Error::Simulation { step: self.steps, message },
                e => e,
            })?;
        }
        let forces = |b: &[u8]| -> Vec<Vec3> {
            bytemuck::pod_collect_to_vec::<u8, [f32; 4]>(b)
                .iter()
                .map(|f| Vec3::new(f[0], f[1], f[2]))
                .collect()
        };
        let hits = |b: &[u8]| -> Vec<GpuHit> { bytemuck::pod_collect_to_vec(b) };
        let (on_a, on_b) = (hits(&bytes[2]), hits(&bytes[3]));
        let mut stats = crate::contact::SurfaceStats::default();
        let mut touching = Vec::new();
        let pushes = |h: &GpuHit| h.found == 1 && h.normal[3] > 0.0;
        // (As the CPU's `SurfaceContact::step`: a vertex of `b` is in contact where a push's
        // stencil gives it a positive weight.)
        for (k, h) in on_a.iter().enumerate().filter(|(_, h)| pushes(h)) {
            stats.b_pushed += 1;
            stats.deepest = stats.deepest.max(h.normal[3]);
            touching.extend(self.b_stencils[k].iter().filter(|(_, u)| *u > 0.0).map(|(v, _)| *v));
        }
        let triangles = &self.sides[1].search;
        let corners = triangles.corners();
        for h in on_b.iter().filter(|h| pushes(h)) {
            stats.a_pushed += 1;
            stats.deepest = stats.deepest.max(h.normal[3]);
            let t = corners[h.triangle as usize];
            for (p, w) in t.iter().zip(h.weights) {
                let stencil = &self.b_stencils[*p as usize];
                touching.extend(stencil.iter().filter(|(_, u)| w * u > 0.0).map(|(v, _)| *v));
            }
        }
        touching.sort_unstable();
        touching.dedup();
        self.stats.set(stats);
        Ok((forces(&bytes[0]), forces(&bytes[1]), touching))
    }

    /// What the step found at the last [`read`](Self::read) (a frame: the step does not read
    /// it back).
    #[must_use]
    pub fn stats(&self) -> crate::contact::SurfaceStats {
        self.stats.get()
    }
}
