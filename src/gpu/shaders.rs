//! The WGSL of each pass, composed without a preprocessor: `common.wgsl` followed by the pass.

/// `(name, composed source)` of every pass, in the order a step runs them.
pub const SHADERS: [(&str, &str); 5] =
    [("bounds", BOUNDS), ("frame", FRAME), ("bin", BIN), ("probe", PROBE), ("resolve", RESOLVE)];

/// Pass 1 (FollowA): A's bounds.
pub const BOUNDS: &str =
    concat!(include_str!("../../shaders/common.wgsl"), include_str!("../../shaders/bounds.wgsl"));
/// Pass 1b: the step's grid center and origin.
pub const FRAME: &str =
    concat!(include_str!("../../shaders/common.wgsl"), include_str!("../../shaders/frame.wgsl"));
/// Pass 2: A into the sparse voxel hash.
pub const BIN: &str =
    concat!(include_str!("../../shaders/common.wgsl"), include_str!("../../shaders/bin.wgsl"));
/// Pass 3: B probes the lists; forces.
pub const PROBE: &str =
    concat!(include_str!("../../shaders/common.wgsl"), include_str!("../../shaders/probe.wgsl"));
/// Pass 4: A's fixed-point totals to f32.
pub const RESOLVE: &str =
    concat!(include_str!("../../shaders/common.wgsl"), include_str!("../../shaders/resolve.wgsl"));
