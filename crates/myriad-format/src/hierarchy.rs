//! The hierarchy, stored in pages as COPC does: a page holds the entries of the nodes of a
//! subtree [`PAGE_LEVELS`] levels deep, and references to the pages of the subtrees below it. A
//! reader of a dataset of any size opens it by reading the root page alone, and walks down only
//! where it needs to. Byte layout: docs/format.md.

use myriad_core::{Aabb, NodeKey, Obb};

pub const HIERARCHY_MAGIC: &[u8; 4] = b"MYRH";
/// Levels of nodes per hierarchy page.
pub const PAGE_LEVELS: u32 = 5;

/// Where a page lies and its CRC-32 (of all its bytes).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct PageRef {
    pub offset: u64,
    pub length: u32,
    pub crc: u32,
}

/// Where a node's splat page lies and what a reader needs with it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SplatInfo {
    pub page: PageRef,
    /// Smallest and largest splat radius of the node.
    pub radius: [f32; 2],
    /// Normal cone: unit axis and the cosine of its half angle (-1: normals in every direction).
    pub cone: [f32; 4],
    /// The node's points are aggregates made for drawing (inner nodes), not original points.
    pub aggregate: bool,
}

/// One node: its key, where its page lies, and its level-of-detail prefixes.
#[derive(Debug, Clone, PartialEq)]
pub struct NodeEntry {
    pub key: NodeKey,
    /// The node page; length 0 for a node without points (kept so that traversal reaches its
    /// descendants).
    pub page: PageRef,
    pub points: u32,
    /// `prefix[l]` points of the node make up its level of detail `l`; the last is `points`.
    pub prefix: Vec<u32>,
    /// Point spacing of each level of detail.
    pub spacing: Vec<f64>,
    /// Where the node's subtree lies, for structures whose nodes are not the cells of their
    /// key's octree (kd-trees); `None`: the key's cube.
    pub bounds: Option<Aabb>,
    /// A tighter outline of the subtree (the contour of Kanzok et al. 2015: an oriented box for
    /// flat nodes); what the selection culls by.
    pub contour: Option<Obb>,
    /// The contour of the node's own points where it is not [`NodeEntry::contour`] (a node that
    /// passes points down: Kanzok et al. 2015 size its detail by the points it stores); `None`: the
    /// contour.
    pub detail: Option<Obb>,
    /// The splat page of an `mwkd` node.
    pub splats: Option<SplatInfo>,
}

impl NodeEntry {
    /// An entry for a node of the key's octree (no stored bounds or contour).
    pub fn new(
        key: NodeKey,
        page: PageRef,
        points: u32,
        prefix: Vec<u32>,
        spacing: Vec<f64>,
    ) -> NodeEntry {
        NodeEntry {
            key,
            page,
            points,
            prefix,
            spacing,
            bounds: None,
            contour: None,
            detail: None,
            splats: None,
        }
    }

    /// Whether the node holds aggregates made for drawing rather than original points.
    pub fn aggregate(&self) -> bool {
        self.splats.is_some_and(|s| s.aggregate)
    }
}

impl NodeEntry {
    /// Where the node's subtree lies: its stored bounds, else its key's cube under `root`.
    pub fn bounds_in(&self, root: &Aabb) -> Aabb {
        self.bounds.unwrap_or_else(|| self.key.bounds(root))
    }
}

/// Flags of an entry's optional parts.
const HAS_BOUNDS: u8 = 1;
const HAS_CONTOUR: u8 = 2;
const HAS_SPLATS: u8 = 4;
const HAS_DETAIL: u8 = 8;

fn put_obb(out: &mut Vec<u8>, c: &Obb) {
    put_f64s(
        out,
        c.center
            .into_iter()
            .chain(c.axes.into_iter().flatten())
            .chain(c.half_extents),
    );
}

fn put_f64s(out: &mut Vec<u8>, v: impl IntoIterator<Item = f64>) {
    for x in v {
        out.extend_from_slice(&x.to_le_bytes());
    }
}

/// A reference to the page of the subtree rooted at `key`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChildPage {
    pub key: NodeKey,
    pub page: PageRef,
}

#[derive(Debug, Clone, PartialEq, Default)]
pub struct HierarchyPage {
    pub nodes: Vec<NodeEntry>,
    pub children: Vec<ChildPage>,
}

/// The root of the page that holds `key`'s entry.
pub fn page_root(key: NodeKey) -> NodeKey {
    let level = key.level / PAGE_LEVELS * PAGE_LEVELS;
    NodeKey {
        level,
        cell: key.cell.map(|c| c >> (key.level - level)),
    }
}

fn put_key(out: &mut Vec<u8>, k: NodeKey) {
    out.push(k.level as u8);
    for c in k.cell {
        out.extend_from_slice(&c.to_le_bytes());
    }
}

fn put_ref(out: &mut Vec<u8>, r: PageRef) {
    out.extend_from_slice(&r.offset.to_le_bytes());
    out.extend_from_slice(&r.length.to_le_bytes());
    out.extend_from_slice(&r.crc.to_le_bytes());
}

impl HierarchyPage {
    pub fn encode(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(12 + self.nodes.len() * 80 + self.children.len() * 29);
        out.extend_from_slice(HIERARCHY_MAGIC);
        out.extend_from_slice(&(self.nodes.len() as u32).to_le_bytes());
        out.extend_from_slice(&(self.children.len() as u32).to_le_bytes());
        for n in &self.nodes {
            put_key(&mut out, n.key);
            put_ref(&mut out, n.page);
            out.extend_from_slice(&n.points.to_le_bytes());
            out.push(n.prefix.len() as u8);
            for (p, s) in n.prefix.iter().zip(&n.spacing) {
                out.extend_from_slice(&p.to_le_bytes());
                out.extend_from_slice(&s.to_le_bytes());
            }
            let flags = if n.bounds.is_some() { HAS_BOUNDS } else { 0 }
                | if n.contour.is_some() { HAS_CONTOUR } else { 0 }
                | if n.splats.is_some() { HAS_SPLATS } else { 0 }
                | if n.detail.is_some() { HAS_DETAIL } else { 0 };
            out.push(flags);
            if let Some(b) = &n.bounds {
                put_f64s(&mut out, b.min.into_iter().chain(b.max));
            }
            if let Some(c) = &n.contour {
                put_obb(&mut out, c);
            }
            if let Some(sp) = &n.splats {
                put_ref(&mut out, sp.page);
                for v in sp.radius.iter().chain(&sp.cone) {
                    out.extend_from_slice(&v.to_le_bytes());
                }
                out.push(sp.aggregate as u8);
            }
            if let Some(c) = &n.detail {
                put_obb(&mut out, c);
            }
        }
        for c in &self.children {
            put_key(&mut out, c.key);
            put_ref(&mut out, c.page);
        }
        out
    }

    /// Decodes a page; an error gives the byte inside the page and what is wrong.
    pub fn decode(b: &[u8]) -> Result<HierarchyPage, (usize, String)> {
        let mut r = Cursor { b, at: 0 };
        if r.bytes(4)? != HIERARCHY_MAGIC {
            return Err((0, "not a hierarchy page (wrong magic)".into()));
        }
        let (nodes, children) = (r.u32()? as usize, r.u32()? as usize);
        // Each entry takes at least 35 bytes, each reference 29: counts beyond that are damage.
        if nodes
            .saturating_mul(35)
            .saturating_add(children.saturating_mul(29))
            > b.len()
        {
            return Err((
                4,
                format!("{nodes} nodes and {children} pages do not fit the page"),
            ));
        }
        let mut page = HierarchyPage::default();
        for _ in 0..nodes {
            let key = r.key()?;
            let pr = r.page_ref()?;
            let points = r.u32()?;
            let levels = r.bytes(1)?[0] as usize;
            let mut prefix = Vec::with_capacity(levels);
            let mut spacing = Vec::with_capacity(levels);
            for _ in 0..levels {
                prefix.push(r.u32()?);
                spacing.push(r.f64()?);
            }
            let at = r.at;
            let flags = r.bytes(1)?[0];
            if flags & !(HAS_BOUNDS | HAS_CONTOUR | HAS_SPLATS | HAS_DETAIL) != 0 {
                return Err((at, format!("unknown entry flags {flags:#x}")));
            }
            let mut e = NodeEntry::new(key, pr, points, prefix, spacing);
            if flags & HAS_BOUNDS != 0 {
                let v = r.f64s::<6>()?;
                e.bounds = Some(Aabb::new([v[0], v[1], v[2]], [v[3], v[4], v[5]]));
            }
            if flags & HAS_CONTOUR != 0 {
                e.contour = Some(r.obb()?);
            }
            if flags & HAS_SPLATS != 0 {
                let page = r.page_ref()?;
                let at = r.at;
                let mut v = [0f32; 6];
                for x in &mut v {
                    *x = f32::from_le_bytes(r.bytes(4)?.try_into().unwrap());
                }
                if v.iter().any(|x| !x.is_finite()) || v[0] > v[1] || v[0] < 0.0 {
                    return Err((at, "invalid splat radii or normal cone".into()));
                }
                e.splats = Some(SplatInfo {
                    page,
                    radius: [v[0], v[1]],
                    cone: [v[2], v[3], v[4], v[5]],
                    aggregate: r.bytes(1)?[0] != 0,
                });
            }
            if flags & HAS_DETAIL != 0 {
                e.detail = Some(r.obb()?);
            }
            page.nodes.push(e);
        }
        for _ in 0..children {
            let key = r.key()?;
            let pr = r.page_ref()?;
            page.children.push(ChildPage { key, page: pr });
        }
        if r.at != b.len() {
            return Err((r.at, "bytes after the last entry".into()));
        }
        Ok(page)
    }
}

struct Cursor<'a> {
    b: &'a [u8],
    at: usize,
}

impl<'a> Cursor<'a> {
    fn bytes(&mut self, n: usize) -> Result<&'a [u8], (usize, String)> {
        if self.b.len() - self.at < n {
            return Err((self.at, "page ends inside an entry".into()));
        }
        self.at += n;
        Ok(&self.b[self.at - n..self.at])
    }
    fn u32(&mut self) -> Result<u32, (usize, String)> {
        Ok(u32::from_le_bytes(self.bytes(4)?.try_into().unwrap()))
    }
    fn f64(&mut self) -> Result<f64, (usize, String)> {
        Ok(f64::from_le_bytes(self.bytes(8)?.try_into().unwrap()))
    }
    /// `N` finite numbers (a box or contour).
    fn f64s<const N: usize>(&mut self) -> Result<[f64; N], (usize, String)> {
        let at = self.at;
        let mut v = [0.0; N];
        for x in &mut v {
            *x = self.f64()?;
        }
        if v.iter().any(|x| !x.is_finite()) {
            return Err((at, "node bounds are not finite".into()));
        }
        Ok(v)
    }
    fn key(&mut self) -> Result<NodeKey, (usize, String)> {
        let at = self.at;
        let level = self.bytes(1)?[0] as u32;
        let cell = [self.u32()?, self.u32()?, self.u32()?];
        if level > 31 || cell.iter().any(|&c| (c as u64) >> level != 0) {
            return Err((
                at,
                format!(
                    "invalid node key {level}-{}-{}-{}",
                    cell[0], cell[1], cell[2]
                ),
            ));
        }
        Ok(NodeKey { level, cell })
    }
    fn obb(&mut self) -> Result<Obb, (usize, String)> {
        let v = self.f64s::<15>()?;
        Ok(Obb {
            center: [v[0], v[1], v[2]],
            axes: [[v[3], v[4], v[5]], [v[6], v[7], v[8]], [v[9], v[10], v[11]]],
            half_extents: [v[12], v[13], v[14]],
        })
    }
    fn page_ref(&mut self) -> Result<PageRef, (usize, String)> {
        let offset = u64::from_le_bytes(self.bytes(8)?.try_into().unwrap());
        Ok(PageRef {
            offset,
            length: self.u32()?,
            crc: self.u32()?,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_page_roots() {
        let k = |level, x, y, z| NodeKey {
            level,
            cell: [x, y, z],
        };
        let page = HierarchyPage {
            nodes: vec![NodeEntry {
                key: k(3, 1, 2, 7),
                page: PageRef {
                    offset: 64,
                    length: 1000,
                    crc: 7,
                },
                points: 99,
                prefix: vec![1, 8, 99],
                spacing: vec![4.0, 2.0, 1.0],
                bounds: Some(Aabb::new([0.5, 1.0, -2.0], [3.0, 4.0, 5.0])),
                contour: Some(Obb {
                    center: [1.0, 2.0, 3.0],
                    axes: [[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]],
                    half_extents: [1.0, 0.5, 0.01],
                }),
                detail: Some(Obb {
                    center: [1.0, 2.0, 3.0],
                    axes: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
                    half_extents: [0.5, 0.25, 0.005],
                }),
                splats: Some(SplatInfo {
                    page: PageRef {
                        offset: 1064,
                        length: 77,
                        crc: 5,
                    },
                    radius: [0.25, 3.0],
                    cone: [0.0, 0.0, 1.0, 0.5],
                    aggregate: true,
                }),
            }],
            children: vec![ChildPage {
                key: k(5, 4, 8, 31),
                page: PageRef {
                    offset: 5000,
                    length: 50,
                    crc: 9,
                },
            }],
        };
        let bytes = page.encode();
        assert_eq!(HierarchyPage::decode(&bytes).unwrap(), page);
        assert!(HierarchyPage::decode(&bytes[..bytes.len() - 1]).is_err());
        assert_eq!(page_root(k(3, 1, 2, 7)), NodeKey::ROOT);
        assert_eq!(page_root(k(7, 100, 4, 5)), k(5, 25, 1, 1));
        assert_eq!(page_root(k(5, 25, 1, 1)), k(5, 25, 1, 1));
    }
}
