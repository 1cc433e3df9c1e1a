//! Surfaces made off the frame's thread (Schiffner et al. 2015 recompute them whenever the view or
//! the drawn points change): the frame hands the worker the points it drew and goes on showing the
//! last surface until the new one is made; a request while one is being made waits for the next
//! frame's (never a queue of stale views). Given a GPU ([`Worker::on`]), the worker runs the
//! cluster, move and reduce steps there (`gpu.rs`), as `render --surface` does; on the CPU where
//! the GPU cannot (a grid beyond its largest binding).

use super::{Built, Surface};
use myriad_lod::Camera;
use std::sync::mpsc::{Receiver, Sender, channel};

struct Job {
    camera: Camera,
    points: Vec<[f64; 3]>,
    colours: Vec<[u8; 4]>,
    surface: Surface,
}

/// A surface made, with the view and parameters it was made for.
pub struct Made {
    pub camera: Camera,
    pub surface: Surface,
    pub built: Built,
    /// Milliseconds from the request to the surface (cluster, move, reduce, reconstruct).
    pub ms: f64,
    /// Where its steps ran: the GPU's name, or "the CPU".
    pub device: String,
}

pub struct Worker {
    jobs: Sender<Job>,
    done: Receiver<Made>,
    busy: bool,
    /// Joined when the worker is dropped: its thread lets go of its GPU before the process
    /// goes on to exit (a driver unloaded on this thread while the main thread runs the exit
    /// handlers crashed the process, 1 exit in about 20 on lavapipe).
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Drop for Worker {
    fn drop(&mut self) {
        // Closing the channel ends the thread's loop.
        drop(std::mem::replace(&mut self.jobs, channel().0));
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Default for Worker {
    fn default() -> Worker {
        Worker::new()
    }
}

impl Worker {
    /// Starts the worker's thread (it ends when the worker is dropped, which waits for it), making surfaces on the
    /// CPU.
    pub fn new() -> Worker {
        Worker::on(None)
    }

    /// [`Worker::new`], the steps on `gpu` where it is one.
    pub fn on(gpu: Option<crate::Gpu>) -> Worker {
        let gpu = gpu.filter(|g| !g.is_cpu());
        let (jobs, inbox) = channel::<Job>();
        let (outbox, done) = channel();
        let thread = std::thread::Builder::new()
            .name("surface".into())
            .spawn(move || {
                while let Ok(job) = inbox.recv() {
                    let t = std::time::Instant::now();
                    let (cam, points, colours) = (&job.camera, &job.points, &job.colours);
                    let on_gpu = gpu.as_ref().and_then(|g| {
                        Some((Built::on(g, cam, points, colours, &job.surface).ok()?, g))
                    });
                    let (built, device) = match on_gpu {
                        Some((b, g)) => (b, g.name.clone()),
                        None => (
                            Built::new(cam, points, colours, &job.surface),
                            "the CPU".to_string(),
                        ),
                    };
                    let made = Made {
                        camera: job.camera,
                        surface: job.surface,
                        built,
                        ms: t.elapsed().as_secs_f64() * 1e3,
                        device,
                    };
                    if outbox.send(made).is_err() {
                        break;
                    }
                }
            })
            .expect("start the surface thread");
        Worker {
            jobs,
            done,
            busy: false,
            thread: Some(thread),
        }
    }

    /// Whether a surface is being made.
    pub fn busy(&self) -> bool {
        self.busy
    }

    /// Asks for the surface of these points seen by `camera`; false (nothing asked) while one
    /// is being made.
    pub fn ask(
        &mut self,
        camera: &Camera,
        points: Vec<[f64; 3]>,
        colours: Vec<[u8; 4]>,
        surface: &Surface,
    ) -> bool {
        if self.busy {
            return false;
        }
        self.busy = self
            .jobs
            .send(Job {
                camera: *camera,
                points,
                colours,
                surface: *surface,
            })
            .is_ok();
        self.busy
    }

    /// The surface finished since the last call, if any (never waits).
    pub fn take(&mut self) -> Option<Made> {
        let made = self.done.try_recv().ok()?;
        self.busy = false;
        Some(made)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_worker_makes_surfaces_without_blocking_and_one_at_a_time() {
        let mut cam = Camera::framing(&myriad_core::Aabb::new([-1.0; 3], [1.0; 3]), 200, 150, 60.0);
        cam.position = [0.0, -6.0, 4.0];
        cam.target = [0.0; 3];
        let points: Vec<[f64; 3]> = (0..40_000)
            .map(|i| {
                [
                    (i % 200) as f64 / 100.0 - 1.0,
                    (i / 200) as f64 / 100.0 - 1.0,
                    0.0,
                ]
            })
            .collect();
        let colours = vec![[200; 4]; points.len()];
        let s = Surface {
            grid: [40, 30, 10],
            ..Surface::default()
        };
        let mut w = Worker::new();
        assert!(w.take().is_none());
        assert!(w.ask(&cam, points.clone(), colours.clone(), &s));
        // A second request while the first is made is refused.
        assert!(!w.ask(&cam, points.clone(), colours.clone(), &s));
        let made = loop {
            if let Some(m) = w.take() {
                break m;
            }
            std::thread::sleep(std::time::Duration::from_millis(2));
        };
        assert!(!w.busy());
        assert_eq!(made.camera, cam);
        assert_eq!(made.built.clustering.inside, points.len());
        assert_eq!(
            made.built.mesh.triangles.len(),
            2 * made.built.clustering.cells.len()
        );
        assert!(w.ask(&cam, points, colours, &s));
    }
}
