//! The surface contact's search on the device (`voxcollide_sim::gpu::surface`, docs/contacts.md
//! "The search on the device") against the CPU's on the same points, bit for bit: each probe's
//! nearest triangle within the cutoff, its weights, the push's direction and depth, with and
//! without the way each probe came in. On a closed breast-like bulge probed by a kidney bean
//! pushed into it, and on the MakeHuman skin as scanned (an open sheet nobody here made)
//! probed by points before and behind it; on a ball grown sixty times past what its search was
//! set up for; and on one grown in place almost to its grid's faces, probed from past them.

#[path = "../../voxcollide/tests/common/adapter.rs"]
mod adapter;
mod common;

use voxcollide::glam::Vec3;
use voxcollide_sim::contact::{SurfaceHit, SurfacePenalty, nearest_pushes};
use voxcollide_sim::gpu::surface::SurfaceSearch;
use voxcollide_sim::mesh::TriangleMesh;

/// `points` in a storage buffer on `ctx`'s device, a `vec4<f32>` each (w 1).
fn upload(ctx: &voxcollide::GpuContext, points: &[Vec3]) -> voxcollide::wgpu::Buffer {
    use voxcollide::wgpu::util::DeviceExt as _;
    let padded: Vec<[f32; 4]> = points.iter().map(|p| p.extend(1.0).to_array()).collect();
    ctx.device().create_buffer_init(&voxcollide::wgpu::util::BufferInitDescriptor {
        label: Some("test points"),
        contents: bytemuck::cast_slice(&padded),
        usage: voxcollide::wgpu::BufferUsages::STORAGE | voxcollide::wgpu::BufferUsages::COPY_DST,
    })
}

/// The device's pushes of `probes` against `mesh` over `partner`, the probes' ways in `entry`.
fn on_device(
    ctx: &voxcollide::GpuContext,
    penalty: SurfacePenalty,
    probes: &[Vec3],
    partner: &[Vec3],
    mesh: &TriangleMesh,
    entry: &[Vec3],
) -> Vec<Option<SurfaceHit>> {
    let device = ctx.device();
    let (probe_buffer, partner_buffer) = (upload(ctx, probes), upload(ctx, partner));
    let mut search = SurfaceSearch::new(ctx, penalty, mesh, partner, probes.len()).unwrap();
    search.set_entry(ctx.queue(), entry);
    let mut encoder = device.create_command_encoder(&Default::default());
    search.record(&mut encoder, &probe_buffer, &partner_buffer).unwrap();
    ctx.queue().submit([encoder.finish()]);
    search.read_hits().unwrap()
}

/// Both searches agree on every probe, to the bit; returns how many were pushed.
fn agree(
    ctx: &voxcollide::GpuContext,
    penalty: SurfacePenalty,
    probes: &[Vec3],
    partner: &[Vec3],
    mesh: &TriangleMesh,
    entry: &[Vec3],
) -> usize {
    let cpu = nearest_pushes(&penalty, probes, partner, mesh, entry);
    let gpu = on_device(ctx, penalty, probes, partner, mesh, entry);
    assert_eq!(cpu.len(), gpu.len());
    let mut differ = Vec::new();
    for (k, (c, g)) in cpu.iter().zip(&gpu).enumerate() {
        let same = match (c, g) {
            (Some(c), Some(g)) => {
                c.triangle == g.triangle
                    && c.weights.map(f32::to_bits) == g.weights.map(f32::to_bits)
                    && c.normal.to_array().map(f32::to_bits) == g.normal.to_array().map(f32::to_bits)
                    && c.depth.to_bits() == g.depth.to_bits()
            }
            (None, None) => true,
            _ => false,
        };
        if !same {
            differ.push(format!("probe {k} at {}: cpu {c:?}, gpu {g:?}", probes[k]));
        }
    }
    assert!(
        differ.is_empty(),
        "{} of {} probes differ:\n{}",
        differ.len(),
        probes.len(),
        differ[..differ.len().min(8)].join("\n")
    );
    cpu.iter().filter(|h| h.is_some()).count()
}

/// Points on a lattice of `step` over the box `lo..hi`, each nudged off it by a hash, so that
/// none sits on a plane of the grid or of the surface by construction.
fn points(lo: Vec3, hi: Vec3, step: f32) -> Vec<Vec3> {
    let n = ((hi - lo) / step).ceil().as_uvec3();
    let mut out = Vec::new();
    for z in 0..=n.z {
        for y in 0..=n.y {
            for x in 0..=n.x {
                let h =
                    (x.wrapping_mul(73_856_093) ^ y.wrapping_mul(19_349_663) ^ z.wrapping_mul(83_492_791))
                        % 1000;
                let nudge = Vec3::new(h as f32, (h * 7 % 1000) as f32, (h * 13 % 1000) as f32) / 1000.0 - 0.5;
                out.push(lo + step * (Vec3::new(x as f32, y as f32, z as f32) + 0.6 * nudge));
            }
        }
    }
    out
}

#[test]
fn the_device_finds_the_pushes_of_a_kidney_pressed_into_a_breast_as_the_cpu_does() {
    let Some(ctx) = adapter::gpu() else { return };
    let breast = common::shapes::breast();
    let kidney = common::shapes::kidney();
    // The kidney turned and pushed 20 mm into the breast's front, and a cloud of points
    // through and about the breast.
    let turn = voxcollide::glam::Mat3::from_rotation_y(0.4);
    let mut probes: Vec<Vec3> =
        kidney.positions.iter().map(|p| turn * *p * 0.6 + Vec3::new(10.0, -5.0, 45.0)).collect();
    probes.extend(points(Vec3::new(-80.0, -90.0, -20.0), Vec3::new(80.0, 75.0, 70.0), 9.0));
    let penalty = SurfacePenalty { stiffness: 1.0, gap: 0.5, reach: 12.0, margin: 1.5 };
    let pushed = agree(&ctx, penalty, &probes, &breast.positions, &breast.mesh, &[]);
    assert!(pushed > 300, "only {pushed} of {} probes pushed", probes.len());
    // Each probe kept to a way in: up for some, down for others (those facing away are passed
    // over, so a probe past a layer's middle is still pushed out the way it came).
    let entry: Vec<Vec3> = (0..probes.len())
        .map(|k| match k % 3 {
            0 => Vec3::ZERO,
            1 => Vec3::Z,
            _ => Vec3::new(0.3, -0.2, -1.0).normalize(),
        })
        .collect();
    let with_entry = agree(&ctx, penalty, &probes, &breast.positions, &breast.mesh, &entry);
    assert!(with_entry > 300, "{with_entry}");
    // A reach smaller than the bulge's facets, a gap of 0, no margin.
    let tight = SurfacePenalty { stiffness: 1.0, gap: 0.0, reach: 2.0, margin: 0.0 };
    assert!(agree(&ctx, tight, &probes, &breast.positions, &breast.mesh, &entry) > 20);
}

#[test]
fn the_device_finds_the_pushes_out_of_a_scanned_skin_as_the_cpu_does() {
    let Some(ctx) = adapter::gpu() else { return };
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenes/makehuman/skin-maxcup-averagefirmness.stl");
    let skin = voxcollide_sim::mesh_io::read_sheet(std::path::Path::new(path)).unwrap();
    // About her left breast (docs/patient.md's box), before and behind the skin.
    let probes = points(Vec3::new(-21.6, 207.8, 64.3), Vec3::new(138.4, 397.8, 237.4), 5.0);
    let penalty = SurfacePenalty { stiffness: 1.0, gap: 0.0, reach: 7.0, margin: 1.0 };
    let pushed = agree(&ctx, penalty, &probes, &skin.positions, &skin.mesh, &[]);
    assert!(pushed > 500, "only {pushed} of {} probes pushed", probes.len());
}

/// A coarse ball of radius 2 (a shell of 4 × 8 cells), its points scaled by `scale`, and the
/// search set up on it as made, its voxel 64 for `penalty`'s cutoff of 30.
fn ball_grown(
    ctx: &voxcollide::GpuContext,
    penalty: SurfacePenalty,
    scale: f32,
    n_probes: usize,
) -> (TriangleMesh, Vec<Vec3>, SurfaceSearch) {
    let material = voxcollide_sim::Material { mass: 1.0, stiffening: 0.0, spring_damping: 0.0, damping: 0.0 };
    let ball =
        voxcollide_sim::bodies::ellipsoid_shell(Vec3::ZERO, Vec3::splat(2.0), 4, 8, 2.0, 10.0, material)
            .unwrap();
    let grown: Vec<Vec3> = ball.pos.iter().map(|p| scale * *p).collect();
    let search = SurfaceSearch::new(ctx, penalty, &ball.surface, &ball.pos, n_probes).unwrap();
    assert_eq!(search.voxel_size(), 64.0);
    (ball.surface, grown, search)
}

/// `search`'s pushes of `probes` against the partner's points `partner`, read back.
fn searched(
    ctx: &voxcollide::GpuContext,
    search: &mut SurfaceSearch,
    probes: &voxcollide::wgpu::Buffer,
    partner: &[Vec3],
) -> Result<Vec<Option<SurfaceHit>>, voxcollide::Error> {
    let mut encoder = ctx.device().create_command_encoder(&Default::default());
    search.record(&mut encoder, probes, &upload(ctx, partner)).unwrap();
    ctx.queue().submit([encoder.finish()]);
    search.read_hits()
}

/// A surface that has grown since the search was set up for it (a shell filling from its
/// deflated start): a coarse ball of radius 2 grown sixty times, its edges some 80 long against
/// a voxel of 64 chosen for edges of 1.3. The walk widens with the longest edge it measures each
/// step (out to the cutoff plus that edge), and the pushes are still the CPU's, to the bit; a
/// walk kept to one voxel each way misses some (checked by hand: 64 of 20,644 probes differ).
#[test]
fn the_device_still_finds_every_push_on_a_surface_grown_past_its_binning() {
    let Some(ctx) = adapter::gpu() else { return };
    let probes: Vec<Vec3> = points(Vec3::splat(-150.0), Vec3::splat(150.0), 8.5)
        .into_iter()
        .filter(|p| (p.length() - 110.0).abs() < 40.0)
        .collect();
    let penalty = SurfacePenalty { stiffness: 1.0, gap: 0.0, reach: 30.0, margin: 0.0 };
    // Set up on the ball as it was; searched on it grown.
    let (mesh, grown, mut search) = ball_grown(&ctx, penalty, 60.0, probes.len());
    let cpu = nearest_pushes(&penalty, &probes, &grown, &mesh, &[]);
    let probe_buffer = upload(&ctx, &probes);
    let gpu = searched(&ctx, &mut search, &probe_buffer, &grown).unwrap();
    let pushed = cpu.iter().filter(|h| h.is_some()).count();
    assert!(pushed > 300, "only {pushed} of {} probes pushed", probes.len());
    let differ = cpu.iter().zip(&gpu).filter(|(c, g)| c != g).count();
    assert_eq!(differ, 0, "{differ} of {} probes differ", probes.len());
    // Grown past the grid that bins it (twice its widest as set up, and a few voxels), its points
    // there go unbinned: the search says so by name instead of missing their pushes.
    let outgrown: Vec<Vec3> = grown.iter().map(|p| p * (200.0 / 60.0)).collect();
    let e = searched(&ctx, &mut search, &probe_buffer, &outgrown).unwrap_err().to_string();
    assert!(e.contains("grew past the grid") && e.contains("--backend cpu"), "{e}");
}

/// A surface grown in place almost to the faces of the grid its search was set up for (the
/// ball 78 times its size: its poles 4 inside the grid's faces, which lie 160 from its middle)
/// is still binned whole, and a probe just outside the grid walks the part of its block inside
/// it: the device finds the pushes and the margin's listings beyond the faces as the CPU does,
/// to the bit. (Before, a probe outside the grid was not searched at all.)
#[test]
fn the_device_searches_from_just_outside_its_grid() {
    let Some(ctx) = adapter::gpu() else { return };
    let probes: Vec<Vec3> = points(Vec3::splat(-190.0), Vec3::splat(190.0), 6.5)
        .into_iter()
        .filter(|p| (p.length() - 156.0).abs() < 25.0)
        .collect();
    // (Listed within 20 outside the surface: probes past the grid's faces get a hit.)
    let penalty = SurfacePenalty { stiffness: 1.0, gap: 0.0, reach: 30.0, margin: 20.0 };
    let (mesh, grown, mut search) = ball_grown(&ctx, penalty, 78.0, probes.len());
    let cpu = nearest_pushes(&penalty, &probes, &grown, &mesh, &[]);
    let gpu = searched(&ctx, &mut search, &upload(&ctx, &probes), &grown).unwrap();
    let outside = |p: &Vec3| p.abs().max_element() > 160.0;
    let beyond = probes.iter().zip(&cpu).filter(|(p, h)| outside(p) && h.is_some()).count();
    assert!(beyond > 20, "only {beyond} probes past the grid's faces have a hit");
    let differ: Vec<String> = probes
        .iter()
        .zip(cpu.iter().zip(&gpu))
        .filter(|(_, (c, g))| c != g)
        .map(|(p, (c, g))| format!("{p}: cpu {c:?}, gpu {g:?}"))
        .collect();
    assert!(
        differ.is_empty(),
        "{} of {} probes differ:\n{}",
        differ.len(),
        probes.len(),
        differ[..differ.len().min(4)].join("\n")
    );
}
