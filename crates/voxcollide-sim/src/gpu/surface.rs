//! The surface contact's search on the device (docs/contacts.md, "The search on the device"):
//! for each probing point, the nearest triangle of the partner's surface within the cutoff and
//! the push out of it, as [`crate::contact::SurfaceContact`] finds it on the CPU, to the bit.
//!
//! **The voxel model finds the candidates.** The partner's points are binned each step by the
//! core's passes ([`GpuCollision::record_binning`]: its grid follows them, its counting sort
//! lays them out by voxel slot), and each probe walks the 3×3×3 block of voxels about its own
//! to the triangles at the points binned there (`shaders/surface_search.wgsl`). A voxel is at
//! least the cutoff plus [`STRETCH`] times the surface's longest edge as it was given (the power
//! of two above it: the core's grids take no other), so every triangle within the cutoff has
//! a corner in the block while no edge has stretched by more than that.
//!
//! **What is not on the device yet.** This is the search alone. The step's forces, the
//! winding-number confirmation of doubtful hits and the entry kept from step to step still run
//! on the host ([`crate::gpu::GpuWorld`] reads the positions back for them); the search is
//! checked against the CPU's on the same positions (`tests/surface_search.rs`).

use bytemuck::{Pod, Zeroable};
use glam::{Vec3, Vec4};
use wgpu::{Buffer, BufferUsages};

use crate::contact::surface::edge_neighbours;
use crate::contact::{SurfaceHit, SurfacePenalty};
use crate::mesh::TriangleMesh;
use voxcollide::error::Error;
use voxcollide::gpu::kernel::{Kernel, Slot};
use voxcollide::gpu::{GpuContext, read_buffers, scoped};
use voxcollide::{Anchor, ContactParams, Direction, GpuCollision, Search, VoxelGrid};

/// How far the surface's edges may stretch beyond their length as given before a triangle
/// within the cutoff could lie outside a probe's block: the voxel is the cutoff plus this times
/// the longest edge.
pub const STRETCH: f32 = 1.5;

/// The search's pass; its shader is the core's `common.wgsl`
/// ([`voxcollide::gpu::shaders::COMMON`]) followed by this.
pub const SURFACE_SEARCH: &str = include_str!("../../shaders/surface_search.wgsl");

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
    _pad: [u32; 3],
}

/// One probe's result. Keep in sync with `SurfaceHit` in `shaders/surface_search.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
struct GpuHit {
    normal: [f32; 4],
    weights: [f32; 4],
    entry: [f32; 4],
    triangle: u32,
    found: u32,
    _pad: [u32; 2],
}

/// The search of one side of a surface contact (one body's points probing the other's
/// surface) on the device.
#[derive(Debug)]
pub struct SurfaceSearch {
    binning: GpuCollision,
    kernel: Kernel,
    uniform: Buffer,
    topology: Buffer,
    hits: Buffer,
    n_probes: u32,
    n_partner: u32,
    /// The bind group, and the buffers it was made over (the probes', the partner's, and the
    /// binning's starts).
    group: Option<([Buffer; 3], wgpu::BindGroup)>,
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
        let longest = mesh
            .triangles
            .iter()
            .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
            .map(|(u, v)| partner[u as usize].distance(partner[v as usize]))
            .filter(|l| l.is_finite())
            .fold(0.0f32, f32::max);
        // (The core's grids take a power of two.)
        let voxel = 2f32.powi((cutoff + STRETCH * longest).log2().ceil() as i32);
        let (lo, hi) = partner
            .iter()
            .filter(|p| p.is_finite())
            .fold((Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)), |(l, h), p| (l.min(*p), h.max(*p)));
        if lo.cmpgt(hi).any() {
            return Err(empty("finite partner point"));
        }
        // Room for the partner to grow to twice its size, and a block past each side.
        let dims = ((2.0 * (hi - lo) / voxel).ceil() + Vec3::splat(4.0)).min(Vec3::splat(1e6)).as_uvec3();
        let grid = VoxelGrid::new(0.5 * (lo + hi), voxel, dims)?;
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
            _pad: [0; 3],
        };
        let source = [voxcollide::gpu::shaders::COMMON, SURFACE_SEARCH].concat();
        scoped(device, || {
            use wgpu::util::DeviceExt as _;
            let init = |label: &str, contents: &[u8], usage: BufferUsages| {
                device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some(label),
                    contents,
                    usage,
                })
            };
            let storage = BufferUsages::STORAGE | BufferUsages::COPY_SRC | BufferUsages::COPY_DST;
            SurfaceSearch {
                binning,
                kernel: Kernel::new(
                    device,
                    "sim surface search",
                    &source,
                    &[
                        Slot::Uniform,
                        Slot::ReadWrite,
                        Slot::Read,
                        Slot::Read,
                        Slot::Uniform,
                        Slot::Read,
                        Slot::Read,
                        Slot::Read,
                        Slot::ReadWrite,
                    ],
                ),
                uniform: init(
                    "sim surface search",
                    bytemuck::bytes_of(&search),
                    BufferUsages::UNIFORM | BufferUsages::COPY_DST,
                ),
                topology: init("sim surface topology", bytemuck::cast_slice(&topology), storage),
                hits: init(
                    "sim surface hits",
                    bytemuck::cast_slice(&vec![GpuHit::default(); n_probes]),
                    storage,
                ),
                n_probes: n_probes as u32,
                n_partner: partner.len() as u32,
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
            let group = scoped(&device, || {
                self.kernel.bind(
                    &device,
                    &[
                        params,
                        state,
                        starts,
                        sorted,
                        &self.uniform,
                        probes,
                        partner,
                        &self.topology,
                        &self.hits,
                    ],
                )
            })?;
            self.group = Some((keys, group));
        }
        let Some((_, group)) = self.group.as_ref() else { unreachable!("the bind group was just made") };
        let max = self.binning.context().device().limits().max_compute_workgroups_per_dimension;
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("sim surface search"),
            timestamp_writes: None,
        });
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
    /// [`Error::Gpu`] / [`Error::DeviceLost`] when the readback fails.
    pub fn read_hits(&self) -> Result<Vec<Option<SurfaceHit>>, Error> {
        let bytes = read_buffers(self.binning.context(), &[(&self.hits, 64 * u64::from(self.n_probes))])?;
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

    /// The voxel of the binning: the power of two at or above the cutoff plus [`STRETCH`] times
    /// the longest edge.
    #[must_use]
    pub fn voxel_size(&self) -> f32 {
        self.binning.grid().voxel_size()
    }
}
