//! Class schemes: the name, colour and visibility of each of the 256 classes a point can hold.
//! The default is the ASPRS table (LAS 1.4 R15, table 17: classes 0 to 22 named by it, every
//! other class "user N"), coloured as the field usually does, with the noise classes (7, low
//! point, and 18, high noise) hidden. A scheme file (`--classes-scheme`, or one kept with a
//! dataset's saved work) renames, recolours, hides or shows any of them.
//!
//! One scheme is in force a process ([`set`], [`current`]): colours are made where the dataset
//! is not known (the renderer's loader threads, the web viewer's workers), as with the terrains
//! of [`crate::ground`].

use std::sync::{Arc, OnceLock, RwLock};

/// The ASPRS standard classes by number (LAS 1.4 R15, table 17); 23 to 63 are reserved there
/// and 64 to 255 the user's: both "user N" here.
pub const ASPRS_NAMES: [&str; 23] = [
    "never classified",
    "unclassified",
    "ground",
    "low vegetation",
    "medium vegetation",
    "high vegetation",
    "building",
    "low point",
    "reserved",
    "water",
    "rail",
    "road surface",
    "overlap",
    "wire guard",
    "wire conductor",
    "transmission tower",
    "wire connector",
    "bridge deck",
    "high noise",
    "overhead structure",
    "ignored ground",
    "snow",
    "temporal exclusion",
];

/// The classes the default scheme hides: low point (noise) and high noise.
pub const HIDDEN_BY_DEFAULT: [u8; 2] = [7, 18];

/// A class scheme: for each class number its name, colour and whether it is hidden.
#[derive(Debug, Clone, PartialEq)]
pub struct Scheme {
    pub names: Vec<String>,
    pub colours: Vec<[u8; 3]>,
    pub hidden: Vec<bool>,
}

impl Default for Scheme {
    fn default() -> Scheme {
        Scheme::asprs()
    }
}

impl Scheme {
    /// The ASPRS table with the usual colours, noise hidden.
    pub fn asprs() -> Scheme {
        Scheme {
            names: (0..=255u8).map(asprs_name).collect(),
            colours: (0..=255u8).map(class_colour).collect(),
            hidden: (0..=255u8)
                .map(|c| HIDDEN_BY_DEFAULT.contains(&c))
                .collect(),
        }
    }

    pub fn name(&self, c: u8) -> &str {
        &self.names[c as usize]
    }

    pub fn colour(&self, c: u8) -> [u8; 3] {
        self.colours[c as usize]
    }

    pub fn is_hidden(&self, c: u8) -> bool {
        self.hidden[c as usize]
    }

    /// The classes this scheme hides.
    pub fn hidden_classes(&self) -> Vec<u8> {
        (0..=255u8).filter(|&c| self.is_hidden(c)).collect()
    }

    /// The classes whose name, colour or visibility differ from the default's.
    pub fn changed(&self) -> Vec<u8> {
        let d = Scheme::asprs();
        (0..=255u8)
            .filter(|&c| {
                let i = c as usize;
                self.names[i] != d.names[i]
                    || self.colours[i] != d.colours[i]
                    || self.hidden[i] != d.hidden[i]
            })
            .collect()
    }
}

/// The ASPRS name of class `c` ("user N" beyond the table).
pub fn asprs_name(c: u8) -> String {
    match ASPRS_NAMES.get(c as usize) {
        Some(n) => (*n).to_string(),
        None => format!("user {c}"),
    }
}

/// Colour of ASPRS class `c` in the default scheme (the usual colours; [`current`] holds the
/// scheme in force).
pub fn class_colour(c: u8) -> [u8; 3] {
    match c {
        0 => [128, 128, 128],
        1 => [170, 170, 170],
        2 => [166, 120, 72],
        3 => [144, 238, 144],
        4 => [60, 179, 113],
        5 => [0, 110, 0],
        6 => [230, 90, 60],
        7 => [255, 0, 255],
        8 => [255, 255, 0],
        9 => [40, 100, 255],
        10 => [150, 75, 0],
        11 => [90, 90, 90],
        12 => [255, 215, 0],
        13 => [255, 255, 255],
        14 => [200, 200, 200],
        15 => [255, 140, 0],
        16 => [200, 100, 200],
        17 => [140, 140, 200],
        18 => [255, 0, 0],
        c => palette(c as u32),
    }
}

/// A distinct colour for a small integer (classes past the table, return numbers, sources,
/// levels).
pub fn palette(i: u32) -> [u8; 3] {
    const P: [[u8; 3]; 10] = [
        [230, 25, 75],
        [60, 180, 75],
        [255, 225, 25],
        [0, 130, 200],
        [245, 130, 48],
        [145, 30, 180],
        [70, 240, 240],
        [240, 50, 230],
        [210, 245, 60],
        [250, 190, 212],
    ];
    P[i as usize % P.len()]
}

fn slot() -> &'static RwLock<Arc<Scheme>> {
    static CURRENT: OnceLock<RwLock<Arc<Scheme>>> = OnceLock::new();
    CURRENT.get_or_init(|| RwLock::new(Arc::new(Scheme::asprs())))
}

/// The scheme in force (the default until [`set`]).
pub fn current() -> Arc<Scheme> {
    slot().read().unwrap_or_else(|p| p.into_inner()).clone()
}

/// Puts `s` in force for every colour made from now on.
pub fn set(s: Scheme) {
    *slot().write().unwrap_or_else(|p| p.into_inner()) = Arc::new(s);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_is_the_asprs_table_with_noise_hidden() {
        let s = Scheme::asprs();
        assert_eq!(s.name(2), "ground");
        assert_eq!(s.name(22), "temporal exclusion");
        assert_eq!(s.name(23), "user 23");
        assert_eq!(s.name(255), "user 255");
        assert_eq!(s.hidden_classes(), vec![7, 18]);
        assert!(s.changed().is_empty());
        let mut t = s.clone();
        t.colours[64] = [1, 2, 3];
        t.hidden[7] = false;
        assert_eq!(t.changed(), vec![7, 64]);
    }
}
