//! Streaming (Scheiblauer 2006, section 4.4): a prioritized load queue, loader threads that read
//! and decode node pages off the frame thread, and an LRU cache of decoded nodes in RAM with a byte
//! budget.
//!
//! Each frame the caller hands [`Loader::request`] the nodes it wants, best first; the queue is
//! replaced, so requests for nodes the view has moved away from are cancelled before they are
//! read. [`Loader::poll`] moves finished loads into the cache without ever waiting, so the frame
//! loop draws what is resident and refines as pages land. A damaged page is reported once and
//! not requested again. Hierarchy pages the selection wants ([`Loader::request_with_pages`])
//! go through the same queue ahead of the nodes (they are small, and the view refines only
//! once they are in); [`Loader::take_pages`] hands over those that landed. What shows a node
//! may give the loader threads its own work on each node read ([`Loader::set_prepare`]: the
//! renderer's colours and GPU words), so that no frame does it (Kanzok et al. 2015, section 3.4).

use crate::cache::Lru;
use myriad_core::{NodeKey, PointBatch};
use myriad_format::splat::Splats;
use myriad_format::{ChildPage, Dataset, HierarchyPage, NodeEntry};
use std::any::Any;
use std::collections::{HashMap, HashSet};
use std::sync::mpsc::{Receiver, Sender, channel};
use std::sync::{Arc, Condvar, Mutex, RwLock};
use std::thread::JoinHandle;

/// Reads and decodes one node's page (a [`Dataset`], or anything that serves pages).
pub trait PageReader: Send + Sync {
    fn read(&self, node: &NodeEntry) -> Result<PointBatch, String>;
    /// The node's splats (`mwkd`), where it has them.
    fn read_splats(&self, _node: &NodeEntry) -> Result<Option<Splats>, String> {
        Ok(None)
    }
    /// Reads and decodes one hierarchy page.
    fn read_hierarchy(&self, page: &ChildPage) -> Result<HierarchyPage, String> {
        Err(format!(
            "hierarchy page of subtree {}: this reader serves none",
            page.key
        ))
    }
}

impl PageReader for Dataset {
    fn read(&self, node: &NodeEntry) -> Result<PointBatch, String> {
        self.read_node(node)
            .map_err(|d| self.damage_error(&d).to_string())
    }
    fn read_splats(&self, node: &NodeEntry) -> Result<Option<Splats>, String> {
        Dataset::read_splats(self, node).map_err(|d| self.damage_error(&d).to_string())
    }
    fn read_hierarchy(&self, page: &ChildPage) -> Result<HierarchyPage, String> {
        self.hierarchy_page(page)
            .map_err(|d| self.damage_error(&d).to_string())
    }
}

/// A reader whose nodes hold only the points a filter keeps (`--classes`, `--where`): the
/// level of detail is drawn from the points kept, and nothing filtered out is ever drawn.
pub struct Filtered {
    pub inner: Arc<dyn PageReader>,
    pub filter: myriad_measure::Bound,
}

impl PageReader for Filtered {
    fn read(&self, node: &NodeEntry) -> Result<PointBatch, String> {
        let mut b = self.inner.read(node)?;
        self.filter.retain(&mut b);
        Ok(b)
    }
    fn read_splats(&self, node: &NodeEntry) -> Result<Option<Splats>, String> {
        let Some(s) = self.inner.read_splats(node)? else {
            return Ok(None);
        };
        // The same points as `read` keeps (the page is read again: only splat datasets pay).
        let keep = self.filter.mask(&self.inner.read(node)?);
        let pick = |i: &usize| keep.get(*i).copied().unwrap_or(false);
        Ok(Some(Splats {
            normals: (s.normals.iter().enumerate())
                .filter(|(i, _)| pick(i))
                .map(|(_, n)| *n)
                .collect(),
            radii: (s.radii.iter().enumerate())
                .filter(|(i, _)| pick(i))
                .map(|(_, r)| *r)
                .collect(),
        }))
    }
    fn read_hierarchy(&self, page: &ChildPage) -> Result<HierarchyPage, String> {
        self.inner.read_hierarchy(page)
    }
}

/// A resident node: its points (what it derefs to) and, in `mwkd` datasets, their splats.
#[derive(Debug, Clone, Default)]
pub struct Loaded {
    pub points: PointBatch,
    pub splats: Option<Splats>,
    /// What the loader's [`Prepare`] made of it on the loader thread, if anything.
    pub prepared: Option<Prepared>,
}

/// What a [`Prepare`] made of a node, and the bytes it holds (counted in the cache's budget).
#[derive(Clone)]
pub struct Prepared {
    pub made: Arc<dyn Any + Send + Sync>,
    pub bytes: usize,
}

impl std::fmt::Debug for Prepared {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Prepared({} bytes)", self.bytes)
    }
}

/// Work a loader thread does on each node it has read (after decoding, before the node is
/// resident), for whoever shows it.
pub type Prepare = Arc<dyn Fn(&NodeEntry, &Loaded) -> Option<Prepared> + Send + Sync>;

impl std::ops::Deref for Loaded {
    type Target = PointBatch;
    fn deref(&self) -> &PointBatch {
        &self.points
    }
}

/// What a loader thread reads.
enum Job {
    Node(NodeEntry),
    Page(ChildPage),
}

/// What it read.
enum Done {
    Node(NodeKey, Result<Loaded, String>),
    Page(NodeKey, Result<HierarchyPage, String>),
}

struct Queue {
    /// Wanted nodes and pages, best last (popped first).
    wanted: Vec<Job>,
    stop: bool,
}

struct Shared {
    queue: Mutex<Queue>,
    ready: Condvar,
    prepare: RwLock<Option<Prepare>>,
}

/// Loader threads and the RAM cache.
pub struct Loader {
    shared: Arc<Shared>,
    results: Receiver<Done>,
    threads: Vec<JoinHandle<()>>,
    cache: Lru<Arc<Loaded>>,
    /// Requested and not yet back (queued or being read): nodes, hierarchy pages.
    pending: HashSet<NodeKey>,
    pending_pages: HashSet<NodeKey>,
    /// Prefetched nodes on their way (not counted in flight: no frame waits for them).
    pending_ahead: HashSet<NodeKey>,
    failed: HashMap<NodeKey, String>,
    failed_pages: HashMap<NodeKey, String>,
    /// Hierarchy pages landed and not taken yet.
    landed_pages: Vec<(NodeKey, HierarchyPage)>,
    /// Hierarchy pages read so far.
    pub pages_read: usize,
}

fn batch_bytes(b: &PointBatch) -> usize {
    b.len() * (b.row_size() + 8)
}

impl Loader {
    /// `threads` loader threads reading through `reader`; the cache keeps at most about
    /// `budget_bytes` of decoded points (nodes used in the current frame are never evicted).
    pub fn new(reader: Arc<dyn PageReader>, threads: usize, budget_bytes: usize) -> Loader {
        let shared = Arc::new(Shared {
            queue: Mutex::new(Queue {
                wanted: Vec::new(),
                stop: false,
            }),
            ready: Condvar::new(),
            prepare: RwLock::new(None),
        });
        let (tx, results) = channel();
        let threads = (0..threads.max(1))
            .map(|i| {
                let (shared, reader, tx): (_, _, Sender<_>) =
                    (shared.clone(), reader.clone(), tx.clone());
                std::thread::Builder::new()
                    .name(format!("myriad-loader-{i}"))
                    .spawn(move || {
                        loop {
                            let job = {
                                let mut q = shared.queue.lock().expect("queue lock");
                                loop {
                                    if q.stop {
                                        return;
                                    }
                                    if let Some(n) = q.wanted.pop() {
                                        break n;
                                    }
                                    q = shared.ready.wait(q).expect("queue lock");
                                }
                            };
                            let done = match job {
                                Job::Node(node) => Done::Node(
                                    node.key,
                                    reader.read(&node).and_then(|points| {
                                        let mut l = Loaded {
                                            splats: reader.read_splats(&node)?,
                                            points,
                                            prepared: None,
                                        };
                                        let prepare =
                                            shared.prepare.read().ok().and_then(|p| p.clone());
                                        if let Some(p) = prepare {
                                            l.prepared = p(&node, &l);
                                        }
                                        Ok(l)
                                    }),
                                ),
                                Job::Page(p) => Done::Page(p.key, reader.read_hierarchy(&p)),
                            };
                            if tx.send(done).is_err() {
                                return;
                            }
                        }
                    })
                    .expect("spawn a loader thread")
            })
            .collect();
        Loader {
            shared,
            results,
            threads,
            cache: Lru::new(budget_bytes),
            pending: HashSet::new(),
            pending_pages: HashSet::new(),
            pending_ahead: HashSet::new(),
            failed: HashMap::new(),
            failed_pages: HashMap::new(),
            landed_pages: Vec::new(),
            pages_read: 0,
        }
    }

    /// Starts a frame: `wanted` lists the nodes to draw, best first. Resident ones are marked
    /// used; missing ones replace the load queue (what is no longer wanted is cancelled).
    pub fn request<'a>(&mut self, wanted: impl IntoIterator<Item = &'a NodeEntry>) {
        self.request_with_pages(wanted, &[]);
    }

    /// [`Loader::request`] with the hierarchy pages the selection wants, best first (they go
    /// ahead of the nodes). Pages that failed are not asked for again.
    pub fn request_with_pages<'a>(
        &mut self,
        wanted: impl IntoIterator<Item = &'a NodeEntry>,
        pages: &[ChildPage],
    ) {
        self.cache.next_frame();
        let mut missing = Vec::new();
        for n in wanted {
            if !self.cache.touch(&n.key) && n.points > 0 && !self.failed.contains_key(&n.key) {
                missing.push(n.clone());
            }
        }
        let mut q = self.shared.queue.lock().expect("queue lock");
        // Queued but no longer wanted: cancelled. Being read: will land anyway.
        for job in q.wanted.drain(..) {
            match job {
                Job::Node(n) => self.pending.remove(&n.key) | self.pending_ahead.remove(&n.key),
                Job::Page(p) => self.pending_pages.remove(&p.key),
            };
        }
        // Prefetched and being read: now wanted, so in flight.
        missing.retain(|n| {
            if self.pending_ahead.remove(&n.key) {
                self.pending.insert(n.key);
            }
            !self.pending.contains(&n.key)
        });
        let mut seen = HashSet::new();
        let pages: Vec<ChildPage> = pages
            .iter()
            .filter(|p| {
                !self.pending_pages.contains(&p.key)
                    && !self.failed_pages.contains_key(&p.key)
                    && seen.insert(p.key)
            })
            .copied()
            .collect();
        for n in &missing {
            self.pending.insert(n.key);
        }
        for p in &pages {
            self.pending_pages.insert(p.key);
        }
        q.wanted = pages
            .into_iter()
            .map(Job::Page)
            .chain(missing.into_iter().map(Job::Node))
            .rev()
            .collect();
        drop(q);
        self.shared.ready.notify_all();
    }

    /// Adds nodes to load ahead behind everything the frame asked for (call after
    /// [`Loader::request_with_pages`]): those not resident, not on their way and not failed.
    /// They are not marked as used: the cache drops them first. Returns how many were queued.
    pub fn prefetch(&mut self, nodes: &[NodeEntry]) -> usize {
        let ahead: Vec<Job> = nodes
            .iter()
            .filter(|n| {
                n.points > 0
                    && !self.cache.contains(&n.key)
                    && !self.pending.contains(&n.key)
                    && !self.pending_ahead.contains(&n.key)
                    && !self.failed.contains_key(&n.key)
            })
            .rev()
            .map(|n| Job::Node(n.clone()))
            .collect();
        let count = ahead.len();
        for j in &ahead {
            if let Job::Node(n) = j {
                self.pending_ahead.insert(n.key);
            }
        }
        let mut q = self.shared.queue.lock().expect("queue lock");
        q.wanted.splice(0..0, ahead);
        drop(q);
        self.shared.ready.notify_all();
        count
    }

    /// Moves finished loads into the cache (hierarchy pages aside, for [`Loader::take_pages`]);
    /// never waits. Returns how many came back (read or failed).
    pub fn poll(&mut self) -> usize {
        let mut landed = 0;
        while let Ok(done) = self.results.try_recv() {
            match done {
                Done::Node(key, r) => {
                    self.pending.remove(&key);
                    self.pending_ahead.remove(&key);
                    match r {
                        Ok(b) => self.insert(key, b),
                        Err(e) => {
                            self.failed.insert(key, e);
                        }
                    }
                }
                Done::Page(key, r) => {
                    self.pending_pages.remove(&key);
                    self.pages_read += 1;
                    match r {
                        Ok(p) => self.landed_pages.push((key, p)),
                        Err(e) => {
                            self.failed_pages.insert(key, e);
                        }
                    }
                }
            }
            landed += 1;
        }
        landed
    }

    /// The hierarchy pages that landed since the last call, by their root's key.
    pub fn take_pages(&mut self) -> Vec<(NodeKey, HierarchyPage)> {
        std::mem::take(&mut self.landed_pages)
    }
    /// Hierarchy pages that could not be read (the subtree's root), with why.
    pub fn failed_pages(&self) -> &HashMap<NodeKey, String> {
        &self.failed_pages
    }
    /// Hierarchy pages queued or being read.
    pub fn pages_in_flight(&self) -> usize {
        self.pending_pages.len()
    }

    /// The work each loader thread does on a node it has read from now on (None: none).
    pub fn set_prepare(&self, prepare: Option<Prepare>) {
        *self
            .shared
            .prepare
            .write()
            .unwrap_or_else(|e| e.into_inner()) = prepare;
    }

    /// Puts a node read elsewhere into the cache (the root a scene read on opening).
    pub fn insert(&mut self, key: NodeKey, node: Loaded) {
        let bytes = batch_bytes(&node)
            + node.splats.as_ref().map_or(0, |s| s.radii.len() * 16)
            + node.prepared.as_ref().map_or(0, |p| p.bytes);
        self.cache.insert(key, Arc::new(node), bytes);
    }

    /// A resident node's points.
    pub fn get(&self, key: &NodeKey) -> Option<Arc<Loaded>> {
        self.cache.get(key).cloned()
    }
    pub fn is_resident(&self, key: &NodeKey) -> bool {
        self.cache.contains(key)
    }
    /// Loads queued or being read (nodes and hierarchy pages).
    pub fn in_flight(&self) -> usize {
        self.pending.len() + self.pending_pages.len()
    }
    /// Nodes whose page could not be read, with why.
    pub fn failed(&self) -> &HashMap<NodeKey, String> {
        &self.failed
    }
    pub fn resident_nodes(&self) -> usize {
        self.cache.len()
    }
    pub fn resident_bytes(&self) -> usize {
        self.cache.bytes()
    }
}

impl Drop for Loader {
    fn drop(&mut self) {
        self.shared.queue.lock().expect("queue lock").stop = true;
        self.shared.ready.notify_all();
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use myriad_format::PageRef;
    use std::sync::atomic::{AtomicUsize, Ordering};

    fn entry(i: u32, points: u32) -> NodeEntry {
        NodeEntry {
            key: NodeKey {
                level: 10,
                cell: [i, 0, 0],
            },
            page: PageRef {
                offset: 64,
                length: 1,
                crc: 0,
            },
            points,
            prefix: vec![points],
            spacing: vec![1.0],
            bounds: None,
            contour: None,
            detail: None,
            splats: None,
        }
    }

    /// Serves pages only when the test lets it: each read waits for a permit.
    struct Gate {
        permits: Mutex<Receiver<()>>,
        reads: AtomicUsize,
        order: Mutex<Vec<u32>>,
    }
    impl PageReader for Gate {
        fn read(&self, n: &NodeEntry) -> Result<PointBatch, String> {
            self.permits
                .lock()
                .unwrap()
                .recv()
                .map_err(|e| e.to_string())?;
            self.reads.fetch_add(1, Ordering::SeqCst);
            self.order.lock().unwrap().push(n.key.cell[0]);
            if n.key.cell[0] == 13 {
                return Err("node 13 is damaged".into());
            }
            Ok(PointBatch {
                positions: vec![[0.0; 3]; n.points as usize],
                ..Default::default()
            })
        }
    }

    /// A gated reader and the sender of its permits.
    fn gate() -> (Sender<()>, Arc<Gate>) {
        let (tx, rx) = channel();
        let gate = Arc::new(Gate {
            permits: Mutex::new(rx),
            reads: AtomicUsize::new(0),
            order: Mutex::new(Vec::new()),
        });
        (tx, gate)
    }

    fn wait_for(l: &mut Loader, n: usize) {
        let mut got = 0;
        while got < n {
            got += l.poll();
            std::thread::yield_now();
        }
    }

    #[test]
    fn frames_never_wait_and_loads_land_in_priority_order() {
        let (tx, gate) = gate();
        let mut l = Loader::new(gate.clone(), 1, usize::MAX);
        let nodes: Vec<NodeEntry> = (0..6).map(|i| entry(i, 100)).collect();
        // The reader is blocked: frame after frame goes by, nothing lands, nothing waits.
        for _ in 0..100 {
            l.request(&nodes);
            assert_eq!(l.poll(), 0);
        }
        assert_eq!(l.resident_nodes(), 0);
        assert_eq!(l.in_flight(), 6);
        // Let pages through one at a time: they land, best first (the first one was taken
        // off the queue while blocked).
        for _ in 0..6 {
            tx.send(()).unwrap();
        }
        wait_for(&mut l, 6);
        assert_eq!(*gate.order.lock().unwrap(), vec![0, 1, 2, 3, 4, 5]);
        assert!(nodes.iter().all(|n| l.is_resident(&n.key)));
        assert_eq!(l.get(&nodes[2].key).unwrap().len(), 100);
    }

    /// Prefetched nodes go behind what the frame asked for, count as nothing in flight, land
    /// in the cache, and are not read twice when the view then wants them.
    #[test]
    fn prefetched_nodes_load_last_and_once() {
        let (tx, gate) = gate();
        let mut l = Loader::new(gate.clone(), 1, usize::MAX);
        let nodes: Vec<NodeEntry> = (0..4).map(|i| entry(i, 10)).collect();
        l.request(&nodes[..2]);
        assert_eq!(l.prefetch(&nodes[1..]), 2);
        assert_eq!(l.in_flight(), 2);
        for _ in 0..3 {
            tx.send(()).unwrap();
        }
        wait_for(&mut l, 3);
        assert_eq!(*gate.order.lock().unwrap(), vec![0, 1, 2]);
        // Node 3 is being read (blocked); the view now wants it: not asked for again.
        while !l.shared.queue.lock().unwrap().wanted.is_empty() {
            std::thread::yield_now();
        }
        l.request(&nodes[3..]);
        assert_eq!(l.in_flight(), 1);
        tx.send(()).unwrap();
        wait_for(&mut l, 1);
        assert!(nodes.iter().all(|n| l.is_resident(&n.key)));
        assert_eq!(gate.reads.load(Ordering::SeqCst), 4);
        assert_eq!(l.prefetch(&nodes), 0);
    }

    #[test]
    fn moving_on_cancels_requests() {
        let (tx, gate) = gate();
        let mut l = Loader::new(gate.clone(), 1, usize::MAX);
        let first: Vec<NodeEntry> = (0..5).map(|i| entry(i, 10)).collect();
        l.request(&first);
        // Wait until the loader holds node 0 (blocked on its permit).
        while l.shared.queue.lock().unwrap().wanted.len() != 4 {
            std::thread::yield_now();
        }
        // The view moves: nodes 20..23 instead.
        let second: Vec<NodeEntry> = (20..23).map(|i| entry(i, 10)).collect();
        l.request(&second);
        for _ in 0..4 {
            tx.send(()).unwrap();
        }
        wait_for(&mut l, 4);
        // Node 0 was already being read; 1..4 were cancelled.
        assert_eq!(*gate.order.lock().unwrap(), vec![0, 20, 21, 22]);
        assert!(!l.is_resident(&first[1].key));
        drop(tx);
    }

    #[test]
    fn lru_eviction_spares_the_current_frame_and_failures_are_kept() {
        let (tx, gate) = gate();
        for _ in 0..100 {
            tx.send(()).unwrap();
        }
        let one = batch_bytes(&PointBatch {
            positions: vec![[0.0; 3]; 100],
            ..Default::default()
        });
        // Room for three nodes.
        let mut l = Loader::new(gate.clone(), 2, 3 * one);
        let all: Vec<NodeEntry> = (0..8).map(|i| entry(i, 100)).collect();
        l.request(&all[0..3]);
        wait_for(&mut l, 3);
        l.request(&all[3..5]);
        wait_for(&mut l, 2);
        // Frame 2 used 3 and 4; of 0, 1, 2 (frame 1) enough went to fit three nodes.
        assert!(l.resident_bytes() <= 3 * one);
        assert!(l.is_resident(&all[3].key) && l.is_resident(&all[4].key));
        assert_eq!(l.resident_nodes(), 3);
        // Nodes in use are never evicted, even over budget.
        l.request(&all[0..6]);
        l.poll();
        for n in &all[3..5] {
            assert!(l.is_resident(&n.key));
        }
        while l.in_flight() > 0 {
            l.poll();
            std::thread::yield_now();
        }
        // A damaged node is reported and not asked for again.
        let bad = entry(13, 5);
        l.request(std::slice::from_ref(&bad));
        while l.failed().is_empty() {
            l.poll();
            std::thread::yield_now();
        }
        let reads = gate.reads.load(Ordering::SeqCst);
        l.request(std::slice::from_ref(&bad));
        assert_eq!(l.in_flight(), 0);
        assert!(l.failed()[&bad.key].contains("damaged"));
        std::thread::sleep(std::time::Duration::from_millis(20));
        assert_eq!(gate.reads.load(Ordering::SeqCst), reads);
    }
}
