// Shared by every pass: the step's parameters and state, voxel indexing, and f32 helpers written
// in the same order as the CPU reference (src/math.rs, src/grid.rs), so both give the same bits.
// Keep Params and State in sync with src/gpu/layout.rs (GpuParams, GpuState).

const WORKGROUP_SIZE: u32 = 64u;
// Slots per invocation and per workgroup (block) of the prefix sum.
const SCAN_PER_INVOCATION: u32 = 16u;
const SCAN_BLOCK: u32 = SCAN_PER_INVOCATION * WORKGROUP_SIZE;

const SEARCH_VOXEL: u32 = 0u;
const SEARCH_NEIGHBOURS: u32 = 1u;
const DIRECTION_PAIRWISE: u32 = 0u;
const DIRECTION_PLANE_NORMAL: u32 = 1u;
const RESPONSE_CONSTANT: u32 = 0u;
const RESPONSE_PENALTY: u32 = 1u;
const ANCHOR_FIXED: u32 = 0u;
const ANCHOR_FOLLOW_A: u32 = 1u;

const STATUS_NON_FINITE_CENTER: u32 = 1u;
const DEGENERATE: f32 = 1e-12;

struct Params {
    center: vec4<f32>,      // the grid center as built
    half_extent: vec4<f32>, // (voxel_size * 0.5) * dims, exact
    dims: vec4<u32>,
    inv: f32,               // 1 / voxel_size
    r2: f32,                // radius * radius (Neighbours)
    magnitude: f32,
    scale: f32,             // 65536 / magnitude
    unit: f32,              // magnitude / 65536
    n_a: u32,
    n_b: u32,
    slot_mask: u32,         // slots - 1 (hashed: a power of two minus one)
    search: u32,
    direction: u32,
    anchor: u32,
    dense: u32,             // 1: a slot per voxel of the grid, at its linear index; 0: hashed
    response: u32,          // RESPONSE_CONSTANT or RESPONSE_PENALTY (the four below: src/eliminate.rs ForceLaw)
    stiffness: f32,
    gap: f32,
    gap_reach: f32,         // gap + reach (the search radius, or the voxel size)
    max_depth: f32,         // magnitude / stiffness
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

struct State {
    center: vec4<f32>,                // this step's grid center
    origin: vec4<f32>,                // this step's origin
    min_key: array<atomic<u32>, 4>,   // per axis, ~key of the minimum over finite A; 0 = none
    max_key: array<atomic<u32>, 4>,   // per axis, key of the maximum; 0 = none
    binned: atomic<u32>,
    colliding: atomic<u32>,
    overflow: atomic<u32>,            // ~(3 * vertex + axis) of the first overflow; 0 = none
    status: atomic<u32>,
    truncated: atomic<u32>,           // ~j of the first B vertex whose walk the driver cut short
    binned_b: atomic<u32>,            // B vertices in the grid (sorted by A's slots)
    _pad1: u32,
    _pad2: u32,
}

// The item of an invocation in a 2D dispatch of rows of `num_workgroups.x` workgroups, so that
// more than 65535 workgroups' worth of items are covered.
fn item_index(gid: vec3<u32>, nwg: vec3<u32>) -> u32 {
    return gid.x + gid.y * nwg.x * WORKGROUP_SIZE;
}

// No NaN or infinity, from the bits (WGSL may assume floats are finite, comparisons may not tell).
fn is_finite_f32(x: f32) -> bool {
    return (bitcast<u32>(x) & 0x7f800000u) != 0x7f800000u;
}

fn is_finite3(p: vec3<f32>) -> bool {
    return is_finite_f32(p.x) && is_finite_f32(p.y) && is_finite_f32(p.z);
}

fn dot3(u: vec3<f32>, v: vec3<f32>) -> f32 {
    return u.x * v.x + u.y * v.y + u.z * v.z;
}

fn dist2(b: vec3<f32>, a: vec3<f32>) -> f32 {
    let d = b - a;
    return dot3(d, d);
}

fn cross3(u: vec3<f32>, v: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(u.y * v.z - u.z * v.y, u.z * v.x - u.x * v.z, u.x * v.y - u.y * v.x);
}

fn axis_index(p: f32, origin: f32, dim: u32) -> vec2<u32> {
    let q = floor((p - origin) * params.inv);
    let inside = q >= 0.0 && q < f32(dim);
    return vec2<u32>(select(0u, u32(q), inside), select(0u, 1u, inside));
}

// The voxel of `p` in xyz, w = 1 when it is inside the grid (and `p` finite), else w = 0.
fn voxel_of(p: vec3<f32>, origin: vec3<f32>) -> vec4<u32> {
    if !is_finite3(p) {
        return vec4<u32>(0u);
    }
    let x = axis_index(p.x, origin.x, params.dims.x);
    let y = axis_index(p.y, origin.y, params.dims.y);
    let z = axis_index(p.z, origin.z, params.dims.z);
    return vec4<u32>(x.x, y.x, z.x, x.y & y.y & z.y);
}

// Blocks of the prefix sum over the slots: slot_mask + 1 slots and the end mark after them.
// Keep in sync with scan_blocks in src/gpu/mod.rs.
fn scan_blocks() -> u32 {
    return (params.slot_mask + 2u + SCAN_BLOCK - 1u) / SCAN_BLOCK;
}

// The slot of voxel `v` in this step's table (params.dense).
fn slot_of(v: vec3<u32>) -> u32 {
    return slot_in(v, params.dense != 0u);
}

// The slot of voxel `v`: its linear index in a dense table, else its hash, masked. The probe
// passes its pipeline constant, so that the compiler keeps one of the two.
fn slot_in(v: vec3<u32>, dense: bool) -> u32 {
    if dense {
        return v.x + params.dims.x * (v.y + params.dims.y * v.z);
    }
    return voxel_hash(v) & params.slot_mask;
}

// Keep in sync with voxel_hash in src/voxel_data.rs: a scrambled hash of the row (y, z) plus x,
// so that a row's voxels sit in consecutive slots.
fn voxel_hash(v: vec3<u32>) -> u32 {
    let h = (v.y * 0x9e3779b1u) ^ (v.z * 0x85ebca77u);
    return (h ^ (h >> 16u)) + v.x;
}
