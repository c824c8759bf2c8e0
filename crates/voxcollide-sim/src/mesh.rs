//! Triangle surfaces over a body's vertices: what is rendered, written to VTK, and used to tell
//! whether a point is inside a closed body.

/// Triangles indexing a body's vertex positions, counter-clockwise seen from outside (so
/// `cross(b - a, c - a)` points out). A closed surface has every edge in exactly two triangles.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct TriangleMesh {
    /// The triangles, as indices into the body's positions.
    pub triangles: Vec<[u32; 3]>,
}
