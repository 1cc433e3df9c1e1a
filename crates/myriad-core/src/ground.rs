//! Heights above the ground, for colouring (`--color above-ground`): a dataset whose edits hold a
//! terrain (`myriad ground`) registers it here under a key (its path), and the column
//! [`Column::AboveGround`](crate::column::Column::AboveGround) then reads a point's elevation
//! minus the terrain's under it, wherever colours are made (the renderer's loader threads, the
//! web viewer's workers), without those knowing the dataset. One terrain a key: registering a
//! key again replaces what it held.

use std::sync::{Arc, Mutex, OnceLock};

/// A terrain's height under a point in plan (`None` where it has none).
pub trait GroundHeight: Send + Sync {
    fn height(&self, x: f64, y: f64) -> Option<f64>;
}

/// No terrain: what a key holds once its dataset's terrain is gone (its ground edit undone).
pub struct NoGround;

impl GroundHeight for NoGround {
    fn height(&self, _: f64, _: f64) -> Option<f64> {
        None
    }
}

type Registered = Vec<(String, Arc<dyn GroundHeight>)>;

fn grounds() -> &'static Mutex<Registered> {
    static GROUNDS: OnceLock<Mutex<Registered>> = OnceLock::new();
    GROUNDS.get_or_init(|| Mutex::new(Vec::new()))
}

/// Registers `g` under `key`; the number the column names it by.
pub fn register(key: &str, g: Arc<dyn GroundHeight>) -> u32 {
    let mut all = grounds().lock().unwrap_or_else(|p| p.into_inner());
    match all.iter().position(|(k, _)| k == key) {
        Some(i) => {
            all[i].1 = g;
            i as u32
        }
        None => {
            all.push((key.to_string(), g));
            all.len() as u32 - 1
        }
    }
}

/// The terrain registered as `id`.
pub fn get(id: u32) -> Option<Arc<dyn GroundHeight>> {
    let all = grounds().lock().unwrap_or_else(|p| p.into_inner());
    all.get(id as usize).map(|(_, g)| g.clone())
}

#[cfg(test)]
mod tests {
    use super::*;

    struct Plane(f64);
    impl GroundHeight for Plane {
        fn height(&self, x: f64, _: f64) -> Option<f64> {
            (x >= 0.0).then_some(self.0)
        }
    }

    #[test]
    fn a_key_holds_one_terrain() {
        let a = register("test-a", Arc::new(Plane(1.0)));
        assert_eq!(get(a).unwrap().height(1.0, 0.0), Some(1.0));
        assert_eq!(register("test-a", Arc::new(Plane(5.0))), a);
        assert_eq!(get(a).unwrap().height(1.0, 0.0), Some(5.0));
        assert_eq!(get(a).unwrap().height(-1.0, 0.0), None);
        assert_ne!(register("test-b", Arc::new(Plane(0.0))), a);
    }
}
