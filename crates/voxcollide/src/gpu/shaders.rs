//! The WGSL of each pass, composed without a preprocessor: `common.wgsl` followed by the pass
//! (the two prefix-sum passes also share `scan_common.wgsl`).

/// `(name, composed source)` of every pass, in the order a step runs them.
pub const SHADERS: [(&str, &str); 10] = [
    ("bounds", BOUNDS),
    ("frame", FRAME),
    ("bin", BIN),
    ("scan", SCAN),
    ("scan_carry", SCAN_CARRY),
    ("scan_add", SCAN_ADD),
    ("sort", SORT),
    ("gather", GATHER),
    ("probe", PROBE),
    ("resolve", RESOLVE),
];

/// Pass 1 (FollowA): A's bounds.
pub const BOUNDS: &str =
    concat!(include_str!("../../shaders/common.wgsl"), include_str!("../../shaders/bounds.wgsl"));
/// Pass 1b: the step's grid center and origin.
pub const FRAME: &str =
    concat!(include_str!("../../shaders/common.wgsl"), include_str!("../../shaders/frame.wgsl"));
/// Pass 2a: A's vertices counted per hash slot, each with its rank in the slot.
pub const BIN: &str =
    concat!(include_str!("../../shaders/common.wgsl"), include_str!("../../shaders/bin.wgsl"));
/// Pass 2b: prefix sums of the slot counts within blocks.
pub const SCAN: &str = concat!(
    include_str!("../../shaders/common.wgsl"),
    include_str!("../../shaders/scan_common.wgsl"),
    include_str!("../../shaders/scan.wgsl")
);
/// Pass 2c: prefix sums of the block totals.
pub const SCAN_CARRY: &str = concat!(
    include_str!("../../shaders/common.wgsl"),
    include_str!("../../shaders/scan_common.wgsl"),
    include_str!("../../shaders/scan_carry.wgsl")
);
/// Pass 2d: the slots' starts.
pub const SCAN_ADD: &str =
    concat!(include_str!("../../shaders/common.wgsl"), include_str!("../../shaders/scan_add.wgsl"));
/// Pass 2e: A's vertices in slot order.
pub const SORT: &str =
    concat!(include_str!("../../shaders/common.wgsl"), include_str!("../../shaders/sort.wgsl"));
/// Pass 2f: a body that kept its order, its new positions gathered into it.
pub const GATHER: &str =
    concat!(include_str!("../../shaders/common.wgsl"), include_str!("../../shaders/gather.wgsl"));
/// Pass 3: B probes the sorted vertices of its voxels; forces.
pub const PROBE: &str =
    concat!(include_str!("../../shaders/common.wgsl"), include_str!("../../shaders/probe.wgsl"));
/// Pass 4: A's fixed-point totals to f32.
pub const RESOLVE: &str =
    concat!(include_str!("../../shaders/common.wgsl"), include_str!("../../shaders/resolve.wgsl"));

/// `common.wgsl` alone: the uniform and state of a step (`Params`, `State`), voxel indexing
/// (`voxel_of`, `slot_of`) and the `f32` helpers in the CPU's order, for other crates' passes
/// that walk a binning ([`GpuCollision::record_binning`](super::GpuCollision::record_binning)).
pub const COMMON: &str = include_str!("../../shaders/common.wgsl");
