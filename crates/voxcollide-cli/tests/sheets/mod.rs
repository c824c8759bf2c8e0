//! Sheets for the patient tests, in ASCII STL: a chest wall or a skin.

/// An open sheet `z = height(x, y)` over `[-half, half]²` as ASCII STL, facing +z.
pub fn sheet_stl(half: f32, cells: u32, height: impl Fn(f32, f32) -> f32) -> String {
    let at = |i: u32, j: u32| {
        let (x, y) =
            (-half + 2.0 * half * i as f32 / cells as f32, -half + 2.0 * half * j as f32 / cells as f32);
        [x, y, height(x, y)]
    };
    let mut out = String::from("solid sheet\n");
    for j in 0..cells {
        for i in 0..cells {
            for t in [[at(i, j), at(i + 1, j), at(i + 1, j + 1)], [at(i, j), at(i + 1, j + 1), at(i, j + 1)]]
            {
                out += "facet normal 0 0 0\nouter loop\n";
                for v in t {
                    out += &format!("vertex {:e} {:e} {:e}\n", v[0], v[1], v[2]);
                }
                out += "endloop\nendfacet\n";
            }
        }
    }
    out + "endsolid sheet\n"
}
