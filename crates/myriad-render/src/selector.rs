//! Selection on its own thread (Kanzok et al. 2015, section 3.4: the frame is split into selection,
//! loading and drawing threads, so that drawing never waits for the others).
//!
//! The frame thread asks for the selection of its camera ([`Selector::ask`]) and draws the newest
//! one that has finished ([`Selector::take`]), the one before while none has: a frame never waits
//! for a traversal, however large the hierarchy. A request asked for while the thread is busy
//! replaces any older one not yet started (the camera moved on); answers come back double
//! buffered (the frame thread holds one selection while the thread fills the next). Occlusion
//! culling needs the resident points of the nodes already selected: the request carries them
//! (shared, not copied), as the frame thread's loader saw them.

use crate::Clip;
use myriad_core::{Aabb, NodeKey};
use myriad_lod::occlusion::Occluder;
use myriad_lod::stream::Loaded;
use myriad_lod::{Camera, Hierarchy, Occlusion, SelectOptions, Selection, select_occluded_from};
use std::collections::{HashMap, HashSet};
use std::sync::{Arc, Condvar, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// The most nodes prefetching asks for in a frame.
pub const PREFETCH_NODES: usize = 64;

/// How a scene selects beyond camera and budget (its settings when asked).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Culling {
    pub clip: Option<Clip>,
    pub occlusion: Occlusion,
    pub occlusion_size: u32,
    /// Prefetching's widening ([`crate::Scene::prefetch`]).
    pub prefetch: f64,
}

/// What to select for.
#[derive(Clone)]
pub struct Request {
    /// The hierarchy as the frame thread knows it now (pages land there; a copy shares them).
    pub hierarchy: Arc<Hierarchy>,
    pub camera: Camera,
    pub options: SelectOptions,
    pub culling: Culling,
    /// Resident points the occluder may splat (those of the nodes selected last).
    pub resident: HashMap<NodeKey, Arc<Loaded>>,
    /// The nodes the last frame's occlusion queries found hidden (`Occlusion::Queries`).
    pub hidden: Arc<HashSet<NodeKey>>,
    /// The culled nodes they found showing (`Occlusion::Checked`).
    pub shown: Arc<HashSet<NodeKey>>,
    /// The nodes the last frame drew (an `mwkd` front is updated from them).
    pub previous: Vec<NodeKey>,
}

/// A finished selection.
#[derive(Debug, Clone)]
pub struct Answer {
    pub selection: Selection,
    /// The camera and point budget it was made for.
    pub camera: Camera,
    pub budget: u64,
    /// How long the traversal took on the selection thread.
    pub took: Duration,
    /// The number [`Selector::ask`] gave its request.
    pub serial: u64,
}

#[derive(Default)]
struct State {
    next: Option<(u64, Request)>,
    done: Option<Answer>,
    busy: bool,
    stop: bool,
}

type Shared = Arc<(Mutex<State>, Condvar)>;

/// The selection thread of one hierarchy.
pub struct Selector {
    shared: Shared,
    thread: Option<JoinHandle<()>>,
    serial: u64,
}

impl Default for Selector {
    fn default() -> Self {
        Self::new()
    }
}

impl Selector {
    pub fn new() -> Selector {
        let shared: Shared = Arc::new((Mutex::new(State::default()), Condvar::new()));
        let s = shared.clone();
        let thread = std::thread::Builder::new()
            .name("myriad-select".into())
            .spawn(move || run(&s))
            .expect("spawn the selection thread");
        Selector {
            shared,
            thread: Some(thread),
            serial: 0,
        }
    }

    /// Asks for a selection, replacing one asked for earlier and not started; never waits.
    /// Returns the request's serial number.
    pub fn ask(&mut self, request: Request) -> u64 {
        self.serial += 1;
        let (lock, ready) = &*self.shared;
        lock.lock().expect("selector lock").next = Some((self.serial, request));
        ready.notify_all();
        self.serial
    }

    /// The newest finished selection not taken yet; never waits.
    pub fn take(&self) -> Option<Answer> {
        self.shared.0.lock().expect("selector lock").done.take()
    }
}

/// What the last frame's occlusion queries found: the nodes hidden (`Occlusion::Queries`), and
/// the culled nodes seen (`Occlusion::Checked`).
pub(crate) struct Queried<'a> {
    pub hidden: &'a HashSet<NodeKey>,
    pub shown: &'a HashSet<NodeKey>,
}

/// A scene's selection: `select_occluded` culling as the request says (the software occluder
/// splats the resident points `points` gives, except for those `queried` saw where its culls are checked; with queries, those it found hidden are culled), and the
/// nodes to prefetch where it widens the view. The frame thread ([`crate::Scene::select`]) and
/// the selection thread both make it here.
pub(crate) fn select_for(
    h: &Hierarchy,
    camera: &Camera,
    options: &SelectOptions,
    how: Culling,
    points: &dyn Fn(&NodeKey) -> Option<Arc<Loaded>>,
    queried: Queried,
    previous: &[NodeKey],
) -> Selection {
    let keep = |cube: &Aabb| Clip::keeps(how.clip, cube);
    let mut occluder = match how.occlusion {
        Occlusion::Software => Some(Occluder::new(camera, how.occlusion_size, points)),
        Occlusion::Queries => Some(Occluder::queried(queried.hidden)),
        Occlusion::Checked => Some(Occluder::checked(
            camera,
            how.occlusion_size,
            points,
            queried.shown,
        )),
        Occlusion::Off => None,
    };
    let mut s = select_occluded_from(h, camera, options, &keep, occluder.as_mut(), previous);
    if how.prefetch > 1.0 {
        s.prefetch =
            myriad_lod::prefetch(h, camera, options, &keep, &s, how.prefetch, PREFETCH_NODES);
    }
    s
}

fn run(shared: &Shared) {
    let (lock, ready) = &**shared;
    loop {
        let (serial, r) = {
            let mut s = lock.lock().expect("selector lock");
            loop {
                if s.stop {
                    return;
                }
                if let Some(next) = s.next.take() {
                    s.busy = true;
                    break next;
                }
                s = ready.wait(s).expect("selector lock");
            }
        };
        let t = Instant::now();
        let selection = select_for(
            &r.hierarchy,
            &r.camera,
            &r.options,
            r.culling,
            &|k| r.resident.get(k).cloned(),
            Queried {
                hidden: &r.hidden,
                shown: &r.shown,
            },
            &r.previous,
        );
        let answer = Answer {
            selection,
            camera: r.camera,
            budget: r.options.budget,
            took: t.elapsed(),
            serial,
        };
        let mut s = lock.lock().expect("selector lock");
        s.done = Some(answer);
        s.busy = false;
        drop(s);
        ready.notify_all();
    }
}

impl Drop for Selector {
    fn drop(&mut self) {
        let (lock, ready) = &*self.shared;
        lock.lock().unwrap_or_else(|e| e.into_inner()).stop = true;
        ready.notify_all();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}
