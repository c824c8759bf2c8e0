//! The crate's one error type: a variant per cause, each message naming the value and the rule.

use glam::{UVec3, Vec3};

use crate::grid::{MAX_DIM, MAX_VOXEL_EXP, MIN_VOXEL_EXP};
use crate::params::{MAX_MAGNITUDE, MIN_MAGNITUDE};

/// Which of the pair of bodies an error is about.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Body {
    /// The indexed body: its vertices go into the voxel lists.
    A,
    /// The probing body: its vertices are looked up in the voxel lists.
    B,
}

impl std::fmt::Display for Body {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Body::A => "A",
            Body::B => "B",
        })
    }
}

/// Everything that can go wrong in `voxcollide`. Bad input is always reported as one of these,
/// never as a panic.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// The voxel size is not a finite, positive, exact power of two `2^k` with `-24 <= k <= 24`.
    #[error(
        "voxel size {value:?} is invalid: it must be a finite, positive, exact power of two 2^k \
         with {MIN_VOXEL_EXP} <= k <= {MAX_VOXEL_EXP}"
    )]
    VoxelSize {
        /// The rejected voxel size.
        value: f32,
    },

    /// A grid dimension is zero or larger than [`MAX_DIM`].
    #[error("grid dims {dims} are invalid: each must be between 1 and {MAX_DIM} (2^24)")]
    Dims {
        /// The rejected dims.
        dims: UVec3,
    },

    /// The bounds handed to the [`Initializer`](crate::Initializer) need more voxels per axis
    /// than a grid may have.
    #[error(
        "a bounding cube of side {side:?} with voxel size {voxel_size:?} and margin {margin} \
         needs {needed} voxels per axis; at most {MAX_DIM} (2^24) are allowed"
    )]
    BoundsTooLarge {
        /// The largest extent of body A over the three axes.
        side: f32,
        /// The voxel size asked for.
        voxel_size: f32,
        /// The margin asked for, in voxels on each side.
        margin: u32,
        /// The voxels per axis that this would need.
        needed: u64,
    },

    /// The grid center is not finite (given so, or the mean of A's bounds overflowed `f32`).
    #[error("grid center {center} is invalid: every component must be finite")]
    NonFiniteCenter {
        /// The rejected center.
        center: Vec3,
    },

    /// A contact response's parameter is out of its range (see [`Response`](crate::params::Response)).
    #[error("contact response {what} {value:?} is invalid: it {rule}")]
    Response {
        /// Which parameter: "stiffness" or "gap".
        what: &'static str,
        /// The rejected value.
        value: f32,
        /// The rule it breaks.
        rule: String,
    },

    /// A body has no vertex at all.
    #[error("body {body} is empty: a body needs at least one vertex")]
    EmptyBody {
        /// The empty body.
        body: Body,
    },

    /// A body has more vertices than can be indexed with `u32`.
    #[error("body {body} has {len} vertices; at most {max} are allowed")]
    TooManyVertices {
        /// The body that is too large.
        body: Body,
        /// Its vertex count.
        len: usize,
        /// The largest count allowed.
        max: usize,
    },

    /// The [`Initializer`](crate::Initializer) was given a body A none of whose vertices is
    /// finite, so it has no bounds.
    #[error(
        "body A has {len} vertices and none is finite: the initializer needs at least one \
         finite vertex to bound"
    )]
    NoFiniteVertex {
        /// The number of (non-finite) vertices in A.
        len: usize,
    },

    /// `Initializer::contact_half` was given a direction that is not finite or is zero.
    #[error("contact-half direction {toward} is invalid: it must be finite and non-zero")]
    Toward {
        /// The rejected direction.
        toward: Vec3,
    },

    /// The force magnitude is not finite or not within the supported range.
    #[error(
        "force magnitude {value:?} is invalid: it must be finite and within \
         [{MIN_MAGNITUDE:?}, {MAX_MAGNITUDE:?}] (the fixed-point scale 65536 / magnitude must \
         stay finite)"
    )]
    Magnitude {
        /// The rejected magnitude.
        value: f32,
    },

    /// The neighbour-search radius is not in `(0, voxel_size]`.
    #[error(
        "search radius {radius:?} is invalid: it must be finite with 0 < radius <= voxel size \
         ({voxel_size:?})"
    )]
    Radius {
        /// The rejected radius.
        radius: f32,
        /// The grid's voxel size, the largest radius allowed.
        voxel_size: f32,
    },

    /// The fixed-point force total of an A vertex left the `i32` range (or its `f32` value is
    /// not finite); a wrapped value is never returned.
    #[error(
        "force on A vertex {vertex} (axis {axis}) overflows: its fixed-point total {count} is \
         outside the i32 range [{min}, {max}]",
        min = i32::MIN,
        max = i32::MAX
    )]
    ForceOverflow {
        /// The A vertex whose force overflowed.
        vertex: u32,
        /// The axis, 0 = x, 1 = y, 2 = z.
        axis: u32,
        /// The exact total, in units of `magnitude / 65536`.
        count: i64,
    },

    /// No usable GPU adapter was found, or its device could not be opened.
    #[error("no GPU adapter: {message}")]
    NoAdapter {
        /// What was searched and what was found.
        message: String,
    },

    /// The device reported an error (validation, out of memory, internal) or failed a readback.
    #[error("GPU error: {message}")]
    Gpu {
        /// The device's message.
        message: String,
    },

    /// The device was lost (a driver reset, a removed GPU, or `Device::destroy`).
    #[error("GPU device lost: {message}")]
    DeviceLost {
        /// What was being done when the loss showed.
        message: String,
    },

    /// A body has more vertices than one storage binding of the device can hold.
    #[error(
        "body {body} has {len} vertices; this device allows at most {max} for it \
         ({limit} = {bytes} bytes, and body {body} takes {per_vertex} bytes a vertex in its \
         largest buffer)"
    )]
    DeviceLimit {
        /// The body that is too large.
        body: Body,
        /// Its vertex count.
        len: usize,
        /// The most vertices the device allows.
        max: usize,
        /// The device limit that sets `max`.
        limit: &'static str,
        /// The device limit's value in bytes.
        bytes: u64,
        /// Bytes a vertex of this body takes in its largest device buffer (16 for B's
        /// positions, 32 for A's fixed-point force accumulators).
        per_vertex: u64,
    },

    /// An app's position buffer is smaller than the vertex count it was given with.
    #[error(
        "position buffer of body {body} has {size} bytes; {len} vertices need {needed} (16 per vec4<f32>)"
    )]
    BufferTooSmall {
        /// Whose buffer.
        body: Body,
        /// The vertex count given.
        len: u32,
        /// The buffer's size in bytes.
        size: u64,
        /// The bytes the count needs.
        needed: u64,
    },

    /// An app's position buffer lacks `BufferUsages::STORAGE`, so it cannot be bound.
    #[error("position buffer of body {body} lacks BufferUsages::STORAGE and cannot be bound to the passes")]
    BufferUsage {
        /// Whose buffer.
        body: Body,
    },

    /// The device cut a voxel-list walk short, so a contact could have been missed: the driver
    /// caps loop iterations (Mesa's llvmpipe/lavapipe at 65535 per loop nest) and the 3×3×3 block
    /// around this B vertex holds more A vertices than that. Use a smaller voxel or another
    /// adapter; the CPU backends have no such cap.
    #[error(
        "the GPU stopped the voxel-list walk of B vertex {b} early (the driver caps a shader's loop \
         iterations, llvmpipe at 65535): its 3×3×3 block holds too many A vertices for this adapter"
    )]
    WalkTruncated {
        /// The first B vertex whose walk was cut short.
        b: u32,
    },

    /// A file could not be written or read.
    #[error("{path}: {message}")]
    Io {
        /// The file.
        path: String,
        /// What went wrong.
        message: String,
    },

    /// A simulation blew up or was set up outside its stable range.
    #[error("simulation failed at step {step}: {message}")]
    Simulation {
        /// The step at which it was seen (0: at setup).
        step: u64,
        /// What was seen and its likely cause.
        message: String,
    },

    /// A mesh file cannot be used as the surface it should be: unreadable, malformed, not
    /// closed, not manifold, or with degenerate triangles.
    #[error("{path}: {message}")]
    Mesh {
        /// The mesh file.
        path: String,
        /// What is wrong with it, with counts and the first offending triangle or edge.
        message: String,
    },

    /// A scene file is malformed or names something that does not exist: where, and why.
    #[error("{file}:{line}:{column}: {key}: {message}")]
    SceneFile {
        /// The file, as given.
        file: String,
        /// 1-based line of the offending key or value (0 when the file could not be read).
        line: usize,
        /// 1-based column.
        column: usize,
        /// The key, as a dotted path where known (e.g. `body[2].material.poisson`).
        key: String,
        /// What is wrong and what is expected.
        message: String,
    },

    /// A value given to the renderer or the command is outside what it supports.
    #[error("{what} = {value} is invalid: {rule}")]
    Invalid {
        /// What the value is.
        what: &'static str,
        /// The value, as given.
        value: String,
        /// The rule it breaks.
        rule: String,
    },
}
