//! A triangle mesh: what surface reconstruction makes and mesh files hold.

/// Triangles over shared vertices, each vertex with a normal and an RGBA8 colour.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Mesh {
    pub positions: Vec<[f64; 3]>,
    pub normals: Vec<[f32; 3]>,
    pub colours: Vec<[u8; 4]>,
    pub triangles: Vec<[u32; 3]>,
}

impl Mesh {
    /// Appends a convex polygon (its corners in order) with one normal and colour, as a fan of
    /// triangles.
    pub fn polygon(&mut self, corners: &[[f64; 3]], normal: [f32; 3], colour: [u8; 4]) {
        if corners.len() < 3 {
            return;
        }
        let first = self.positions.len() as u32;
        for &c in corners {
            self.positions.push(c);
            self.normals.push(normal);
            self.colours.push(colour);
        }
        for k in 1..corners.len() as u32 - 1 {
            self.triangles.push([first, first + k, first + k + 1]);
        }
    }

    /// The box of every vertex; None when there is none.
    pub fn bounds(&self) -> Option<crate::Aabb> {
        let mut it = self.positions.iter();
        let first = *it.next()?;
        let mut b = crate::Aabb::new(first, first);
        for &p in it {
            b.extend(p);
        }
        Some(b)
    }
}
