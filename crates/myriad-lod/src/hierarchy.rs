//! The outer tree as far as it is known. A dataset stores its hierarchy in pages of
//! [`PAGE_LEVELS`] levels (as COPC does); opening it reads the root page alone, and the pages
//! below are read when the selection wants to refine a node whose children lie on them
//! ([`Selection::pages`](crate::Selection::pages)), by the loader threads like node pages.
//!
//! [`Hierarchy`] holds the loaded pages, each behind an `Arc`: a copy for the selection thread
//! costs a map of pointers, not the entries, and a page landing changes the frame thread's copy
//! only. [`PageCache`] bounds the memory: the pages the last frames did not use go first, with
//! the pages below them (unreachable without them); the root page always stays.

use crate::selection::Selection;
use myriad_core::{Aabb, NodeKey, Obb};
use myriad_format::hierarchy::{PAGE_LEVELS, page_root};
use myriad_format::{ChildPage, HierarchyPage, NodeEntry};
use std::collections::{HashMap, HashSet};
use std::sync::Arc;

/// One loaded hierarchy page: its entries and the pages below it.
#[derive(Debug, Default)]
struct Page {
    nodes: HashMap<NodeKey, NodeEntry>,
    /// The pages of the subtrees below this one, by their root's key.
    below: HashMap<NodeKey, ChildPage>,
    /// What it holds in memory (an estimate: entries, their level tables, the maps).
    bytes: usize,
}

impl Page {
    fn new(nodes: impl IntoIterator<Item = NodeEntry>, below: Vec<ChildPage>) -> Page {
        let nodes: HashMap<NodeKey, NodeEntry> = nodes.into_iter().map(|e| (e.key, e)).collect();
        let entry = std::mem::size_of::<(NodeKey, NodeEntry)>() + 16;
        let bytes = 64
            + nodes
                .values()
                .map(|e| entry + e.prefix.len() * 12)
                .sum::<usize>()
            + below.len() * (std::mem::size_of::<(NodeKey, ChildPage)>() + 16);
        Page {
            nodes,
            below: below.into_iter().map(|c| (c.key, c)).collect(),
            bytes,
        }
    }
}

/// The outer tree, as far as its pages are loaded.
#[derive(Debug, Clone)]
pub struct Hierarchy {
    pub root: Aabb,
    /// Loaded pages by the key of their root node.
    pages: HashMap<NodeKey, Arc<Page>>,
    /// Whether every node is its key's octree cell (no stored bounds): then points lie in their
    /// key's cube and the drawn tree can size them per point.
    cells: bool,
    /// `mwkd`: nodes hold splats, inner nodes aggregates that their children replace.
    splats: bool,
    /// Some node has a contour (layered): benefits are the contours', not the cubes'.
    contours: bool,
    /// The deepest level of the whole tree (the metadata's depth when pages are loaded lazily).
    pub(crate) max_level: u32,
    /// Cull nodes whose normal cone faces away (only where normals have a sign: the input's).
    pub cull_backfaces: bool,
    /// Which of a layered node's contours sizes its detail.
    pub detail_contour: DetailContour,
    nodes: usize,
    bytes: usize,
}

/// Which contour sizes a layered node's detail (Kanzok et al. 2015, section 3.2.2: the projected
/// size of the node's contour; the rule binds on flat contours only). Both hold the node's own
/// points.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum DetailContour {
    /// The subtree's, which culling uses (datasets built before own contours were stored).
    Subtree,
    /// The node's own points' where the dataset stores it (Kanzok et al. 2015), else the subtree's.
    Own,
    /// Of the two, the flat one that covers fewer pixels (the measured best: bench culling
    /// --detail-contour).
    #[default]
    Tighter,
}

impl DetailContour {
    pub const ALL: [DetailContour; 3] = [
        DetailContour::Subtree,
        DetailContour::Own,
        DetailContour::Tighter,
    ];
    pub fn name(self) -> &'static str {
        match self {
            DetailContour::Subtree => "subtree",
            DetailContour::Own => "own",
            DetailContour::Tighter => "tighter",
        }
    }
    /// The contours that may size `e`'s detail.
    pub fn of(self, e: &NodeEntry) -> [Option<&Obb>; 2] {
        match self {
            DetailContour::Subtree => [e.contour.as_ref(), None],
            DetailContour::Own => [e.detail.as_ref().or(e.contour.as_ref()), None],
            DetailContour::Tighter => [e.contour.as_ref(), e.detail.as_ref()],
        }
    }
}

impl Hierarchy {
    /// A hierarchy known whole: every entry given.
    pub fn new(root: Aabb, entries: impl IntoIterator<Item = NodeEntry>) -> Hierarchy {
        let mut by_page: HashMap<NodeKey, Vec<NodeEntry>> = HashMap::new();
        for e in entries {
            by_page.entry(page_root(e.key)).or_default().push(e);
        }
        let mut h = Hierarchy::empty(root, 0);
        for (key, nodes) in by_page {
            h.add(key, Page::new(nodes, Vec::new()));
        }
        h
    }

    /// A hierarchy of which the root page alone is known; `depth` is the whole tree's.
    pub fn from_root_page(root: Aabb, page: HierarchyPage, depth: u32) -> Hierarchy {
        let mut h = Hierarchy::empty(root, depth);
        h.add(NodeKey::ROOT, Page::new(page.nodes, page.children));
        h
    }

    fn empty(root: Aabb, depth: u32) -> Hierarchy {
        Hierarchy {
            root,
            pages: HashMap::new(),
            cells: true,
            splats: false,
            contours: false,
            max_level: depth,
            cull_backfaces: false,
            detail_contour: DetailContour::default(),
            nodes: 0,
            bytes: 0,
        }
    }

    fn add(&mut self, key: NodeKey, page: Page) {
        for e in page.nodes.values() {
            self.cells &= e.bounds.is_none();
            self.splats |= e.splats.is_some();
            self.contours |= e.contour.is_some();
            self.max_level = self.max_level.max(e.key.level);
        }
        self.nodes += page.nodes.len();
        self.bytes += page.bytes;
        self.pages.insert(key, Arc::new(page));
    }

    /// Takes in a page read from the dataset, where it belongs: below a loaded page that lists
    /// it, and not loaded yet. Returns whether it was taken.
    pub fn insert_page(&mut self, key: NodeKey, page: HierarchyPage) -> bool {
        if self.pages.contains_key(&key) || self.page_ref(&key).is_none() {
            return false;
        }
        self.add(key, Page::new(page.nodes, page.children));
        true
    }

    /// Drops a loaded page and the loaded pages below it (never the root page); returns how
    /// many pages went.
    pub fn remove_page(&mut self, key: &NodeKey) -> usize {
        if key.level == 0 {
            return 0;
        }
        let Some(page) = self.pages.remove(key) else {
            return 0;
        };
        self.nodes -= page.nodes.len();
        self.bytes -= page.bytes;
        1 + page
            .below
            .keys()
            .map(|k| self.remove_page(k))
            .sum::<usize>()
    }

    /// Where the page rooted at `key` lies, as the loaded page above it lists it.
    pub fn page_ref(&self, key: &NodeKey) -> Option<ChildPage> {
        if key.level == 0 || !key.level.is_multiple_of(PAGE_LEVELS) {
            return None;
        }
        let above = self.pages.get(&page_root(key.parent()))?;
        above.below.get(key).copied()
    }

    /// Whether the page rooted at `key` is loaded.
    pub fn has_page(&self, key: &NodeKey) -> bool {
        self.pages.contains_key(key)
    }

    /// The pages below `key` that hold its children and are not loaded yet (only a node on
    /// a page's last level has children on other pages).
    pub fn unloaded_below(&self, key: &NodeKey) -> impl Iterator<Item = ChildPage> + '_ {
        let page = (key.level + 1)
            .is_multiple_of(PAGE_LEVELS)
            .then(|| self.pages.get(&page_root(*key)))
            .flatten();
        let key = *key;
        (0..8).filter_map(move |o| {
            let c = key.child(o);
            let r = page?.below.get(&c)?;
            (!self.pages.contains_key(&c)).then_some(*r)
        })
    }

    /// Whether nodes hold splats that replace their parents' when drawn (`mwkd`,
    /// Goswami et al. 2010): select with [`select_front`](crate::select_front).
    pub fn splats(&self) -> bool {
        self.splats
    }
    /// Whether a known node has a contour (layered).
    pub fn contours(&self) -> bool {
        self.contours
    }
    /// Whether nodes are the cells of their keys' octree (octree and layered structures; kd-trees
    /// store their bounds instead).
    pub fn cells(&self) -> bool {
        self.cells
    }
    /// Where a node's subtree lies: its stored bounds, else its key's cube.
    pub fn bounds(&self, key: &NodeKey) -> Aabb {
        match self.get(key).and_then(|e| e.bounds) {
            Some(b) => b,
            None => key.bounds(&self.root),
        }
    }
    pub fn get(&self, key: &NodeKey) -> Option<&NodeEntry> {
        self.pages.get(&page_root(*key))?.nodes.get(key)
    }
    /// Known nodes.
    pub fn len(&self) -> usize {
        self.nodes
    }
    pub fn is_empty(&self) -> bool {
        self.nodes == 0
    }
    /// Loaded pages.
    pub fn pages(&self) -> usize {
        self.pages.len()
    }
    /// Memory the loaded pages take (an estimate).
    pub fn bytes(&self) -> usize {
        self.bytes
    }
    /// Every known page ref not loaded yet (the rest of the tree, for walking all of it).
    pub fn unloaded(&self) -> Vec<ChildPage> {
        let mut out: Vec<ChildPage> = self
            .pages
            .values()
            .flat_map(|p| p.below.values())
            .filter(|c| !self.pages.contains_key(&c.key))
            .copied()
            .collect();
        out.sort_by_key(|c| c.key);
        out
    }
    pub fn children(&self, key: &NodeKey) -> impl Iterator<Item = &NodeEntry> {
        (0..8).filter_map(move |o| self.get(&key.child(o)))
    }

    /// Whether `key` has no children, as far as can be known (a node whose children's page is
    /// not read yet may have some: not a leaf).
    pub fn is_leaf(&self, key: &NodeKey) -> bool {
        self.children(key).next().is_none() && self.unloaded_below(key).next().is_none()
    }
    /// Every known node's key, in no particular order.
    pub fn keys(&self) -> impl Iterator<Item = NodeKey> + '_ {
        self.pages.values().flat_map(|p| p.nodes.keys().copied())
    }
    /// Every known node's entry, in no particular order.
    pub fn entries(&self) -> impl Iterator<Item = &NodeEntry> + '_ {
        self.pages.values().flat_map(|p| p.nodes.values())
    }
    /// Original points in the known tree (aggregates made for drawing not counted).
    pub fn points(&self) -> u64 {
        self.entries()
            .filter(|n| !n.aggregate())
            .map(|n| n.points as u64)
            .sum()
    }
}

/// Bounds the memory of a lazily loaded hierarchy: remembers the frame each page was last used
/// in, and drops the least recently used pages (with the pages below them) while the loaded
/// pages take more than `budget` bytes. Pages used in the current frame stay, even beyond it.
#[derive(Debug)]
pub struct PageCache {
    pub budget: usize,
    frame: u64,
    used: HashMap<NodeKey, u64>,
    /// Pages dropped so far.
    pub evicted: usize,
}

impl PageCache {
    pub fn new(budget: usize) -> PageCache {
        PageCache {
            budget,
            frame: 0,
            used: HashMap::new(),
            evicted: 0,
        }
    }

    /// Marks the pages a frame's selection used: those its traversal entered, and those that
    /// hold its nodes and their ancestors.
    pub fn touch(&mut self, s: &Selection) {
        self.frame += 1;
        let mut seen = HashSet::new();
        for &k in s.used_pages.iter().chain(s.nodes.iter().map(|n| &n.key)) {
            let mut p = page_root(k);
            while seen.insert(p) {
                self.used.insert(p, self.frame);
                if p.level == 0 {
                    break;
                }
                p = page_root(p.parent());
            }
        }
    }

    /// Drops pages from `h` until it fits the budget or only pages in use are left.
    pub fn evict(&mut self, h: &mut Arc<Hierarchy>) {
        if h.bytes() <= self.budget {
            return;
        }
        let mut order: Vec<(u64, NodeKey)> = h
            .pages
            .keys()
            .filter(|k| k.level > 0)
            .map(|k| (self.used.get(k).copied().unwrap_or(0), *k))
            .filter(|(f, _)| *f < self.frame)
            .collect();
        // Oldest first; of the same age, the deepest first.
        order.sort_by_key(|&(f, k)| (f, std::cmp::Reverse(k.level), k));
        let h = Arc::make_mut(h);
        for (_, k) in order {
            if h.bytes() <= self.budget {
                break;
            }
            self.evicted += h.remove_page(&k);
        }
        self.used.retain(|k, _| h.pages.contains_key(k));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use myriad_format::PageRef;

    fn entry(key: NodeKey) -> NodeEntry {
        NodeEntry::new(
            key,
            PageRef {
                offset: 64,
                length: 10,
                crc: 0,
            },
            10,
            vec![10],
            vec![1.0],
        )
    }

    fn key(level: u32, x: u32) -> NodeKey {
        NodeKey {
            level,
            cell: [x, 0, 0],
        }
    }

    fn page(root: NodeKey, below: &[NodeKey]) -> HierarchyPage {
        let mut nodes = vec![entry(root)];
        let mut k = root;
        while !(k.level + 1).is_multiple_of(PAGE_LEVELS) {
            k = k.child(0);
            nodes.push(entry(k));
        }
        HierarchyPage {
            nodes,
            children: below
                .iter()
                .map(|&key| ChildPage {
                    key,
                    page: PageRef {
                        offset: 1000 + key.cell[0] as u64,
                        length: 10,
                        crc: 0,
                    },
                })
                .collect(),
        }
    }

    /// The root page alone at first; a page comes in only below a loaded page that lists it;
    /// removing a page removes the pages below it.
    #[test]
    fn pages_come_in_below_known_pages_and_go_with_their_subtrees() {
        let root = Aabb::new([0.0; 3], [1.0; 3]);
        let (a, b) = (key(5, 0), key(5, 1));
        let deep = key(10, 0);
        let mut h = Hierarchy::from_root_page(root, page(NodeKey::ROOT, &[a, b]), 12);
        assert_eq!((h.len(), h.pages(), h.max_level), (5, 1, 12));
        let last = key(4, 0);
        let want: Vec<NodeKey> = h.unloaded_below(&last).map(|c| c.key).collect();
        assert_eq!(want, vec![a, b]);
        assert_eq!(h.unloaded_below(&key(3, 0)).count(), 0);
        // Not listed anywhere loaded: refused.
        assert!(!h.insert_page(deep, page(deep, &[])));
        assert!(h.insert_page(a, page(a, &[deep])));
        assert!(!h.insert_page(a, page(a, &[deep])));
        assert!(h.insert_page(deep, page(deep, &[])));
        assert_eq!((h.len(), h.pages()), (15, 3));
        assert_eq!(h.get(&key(7, 0)).unwrap().points, 10);
        assert_eq!(h.children(&key(4, 0)).count(), 1);
        assert_eq!(h.unloaded().iter().map(|c| c.key).collect::<Vec<_>>(), [b]);
        let bytes = h.bytes();
        assert_eq!(h.remove_page(&a), 2);
        assert_eq!((h.len(), h.pages()), (5, 1));
        assert!(h.bytes() < bytes);
        assert_eq!(h.remove_page(&NodeKey::ROOT), 0);
    }
}
