//! `myriad bench ground SCAN...`: the ground `myriad ground` finds against the providers' labels
//! (class 2), per scan: type I error (ground points it calls something else), type II (other
//! points it calls ground), total error, the points without a terrain under them, time and peak
//! memory. Every point of the dataset is compared, as stored (noise, classes 7 and 18, left
//! out, as the filter leaves it out). Each scan is converted first where it is not a dataset.

use anyhow::{Result, anyhow};
use clap::Args;
use myriad_format::Dataset;
use myriad_measure::ground::surface::Surface;
use myriad_measure::ground::{self, Rule, is_noise};
use std::path::PathBuf;

#[derive(Args)]
pub struct GroundBenchArgs {
    /// Labelled scans or datasets
    #[arg(required = true)]
    scans: Vec<PathBuf>,
    /// The grid's cell, in the data's units [default: --spacings times the mean spacing]
    #[arg(long)]
    cell: Option<f64>,
    #[arg(long, default_value_t = 2.5)]
    spacings: f64,
    #[arg(long, default_value_t = 0.15)]
    slope: f64,
    /// Lengths in metres
    #[arg(long, default_value_t = 30.0)]
    window: f64,
    #[arg(long, default_value_t = 64.0)]
    fill: f64,
    #[arg(long, default_value_t = 0.5)]
    threshold: f64,
    #[arg(long, default_value_t = 1.25)]
    scalar: f64,
    #[arg(long, default_value_t = 1.0)]
    low: f64,
    #[arg(long, default_value_t = 2)]
    isolated: usize,
    /// Classes left out of the comparison (a provider's classes that say nothing of the
    /// ground, such as overlap)
    #[arg(long)]
    ignore: Option<String>,
    /// The labels that are the ground (roads, class 11, are ground in `synth`'s scenes)
    #[arg(long, default_value = "2")]
    ground_classes: String,
    /// A tile's side in cells
    #[arg(long, default_value_t = 1024)]
    tile: usize,
}

/// Errors of one scan's classification against its labels.
#[derive(Debug, Clone, Copy)]
pub struct Errors {
    pub ground: u64,
    pub other: u64,
    /// Ground called something else.
    pub type1: u64,
    /// Something else called ground.
    pub type2: u64,
    /// Points without a terrain under them (they keep their labels).
    pub bare: u64,
    /// Squared heights of the labelled ground points above the terrain (with one), and their
    /// count: how far the terrain is from the labelled ground, whatever the classes.
    pub ground_sq: f64,
    pub ground_on: u64,
    /// Type II errors by the label's class.
    pub type2_by_class: [u64; 256],
}

impl Default for Errors {
    fn default() -> Errors {
        Errors {
            ground: 0,
            other: 0,
            type1: 0,
            type2: 0,
            bare: 0,
            ground_sq: 0.0,
            ground_on: 0,
            type2_by_class: [0; 256],
        }
    }
}

impl Errors {
    pub fn total(&self) -> f64 {
        (self.type1 + self.type2) as f64 / (self.ground + self.other).max(1) as f64
    }
}

/// The errors of the terrain in `surface` with `rule` against the labels of `ds` as stored.
pub fn errors(
    ds: &Dataset,
    surface: &Surface,
    rule: &Rule,
    ignore: &[u8],
    ground_classes: &[u8],
) -> Result<Errors> {
    let mut e = Errors::default();
    let (nodes, damage) = ds.nodes();
    if let Some(d) = damage.first() {
        return Err(ds.damage_error(d).into());
    }
    for n in nodes.iter().filter(|n| n.points > 0 && !n.aggregate()) {
        let b = ds
            .read_node_stored(n, &ds.meta.schema)
            .map_err(|d| ds.damage_error(&d))?;
        let Some(classes) = &b.classification else {
            return Err(anyhow!(
                "{}: no classes to compare with",
                ds.path().display()
            ));
        };
        for (p, &c) in b.positions.iter().zip(classes) {
            if is_noise(c) || ignore.contains(&c) {
                continue;
            }
            let height = surface
                .tile_of(p[0], p[1])
                .map(|t| surface.tile(t).map(|cells| (t, cells)))
                .transpose()
                .map_err(|m| anyhow!(m))?
                .and_then(|(t, cells)| surface.height(t, &cells?, p[0], p[1]));
            let called = match height {
                None => {
                    e.bare += 1;
                    c
                }
                Some(h) => {
                    if ground_classes.contains(&c) {
                        e.ground_sq += (p[2] - h.z) * (p[2] - h.z);
                        e.ground_on += 1;
                    }
                    match surface.is_isolated(p[0], p[1], p[2]) {
                        true => 7,
                        false => rule.class(c, p[2] - h.z, h.slope).unwrap_or(c),
                    }
                }
            };
            let called = ground_classes.contains(&called);
            if ground_classes.contains(&c) {
                e.ground += 1;
                e.type1 += !called as u64;
            } else {
                e.other += 1;
                e.type2 += called as u64;
                e.type2_by_class[c as usize] += called as u64;
            }
        }
    }
    Ok(e)
}

pub fn run(a: GroundBenchArgs) -> Result<()> {
    let o = ground::Options {
        cell: a.cell,
        spacings: a.spacings,
        slope: a.slope,
        window: a.window,
        fill: a.fill,
        threshold: a.threshold,
        scalar: a.scalar,
        low: a.low,
        isolated: a.isolated,
    };
    let ignore = match &a.ignore {
        Some(c) => myriad_measure::Filter::parse_classes(c).map_err(|m| anyhow!(m))?,
        None => Vec::new(),
    };
    let ground_classes =
        myriad_measure::Filter::parse_classes(&a.ground_classes).map_err(|m| anyhow!(m))?;
    let scratch = std::env::temp_dir().join(format!("myriad-bench-ground-{}", std::process::id()));
    std::fs::create_dir_all(&scratch)?;
    println!("{o:?}, ignoring classes {ignore:?}");
    println!(
        "| scan | cell | points | ground | type I | type II | total | no terrain | terrain RMS at ground | time | peak |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    for scan in &a.scans {
        let dataset = if myriad_format::is_dataset(scan) {
            scan.clone()
        } else {
            // Built in the scratch folder: nothing is written beside the scans.
            let myr = scratch.join("scan.myr");
            let co = myriad_build::convert::ConvertOptions {
                force: true,
                ..myriad_build::convert::ConvertOptions::new(&myr)
            };
            myriad_build::convert::convert(
                std::slice::from_ref(scan),
                &co,
                &myriad_build::report::Silent,
            )?;
            myr
        };
        let ds = Dataset::open_stored(&dataset)?;
        let (p, rule) = o.resolve(ds.meta.points, &ds.meta.bounds, ds.meta.crs.as_deref());
        if p.window > 4096 || p.fill > 4096 {
            return Err(anyhow!("--window and --fill: at most 4,096 cells"));
        }
        let out = scratch.join(format!(
            "{}.surface",
            scan.file_name().unwrap_or_default().to_string_lossy()
        ));
        let _ = std::fs::remove_file(&out);
        // The peak resident memory counts from here (Linux: "5" to clear_refs resets it).
        let _ = std::fs::write("/proc/self/clear_refs", "5");
        let t = std::time::Instant::now();
        ground::build(&ds, &p, a.isolated, a.tile, &out, &|_, _| {})?;
        let seconds = t.elapsed().as_secs_f64();
        let peak = myriad_io::process::peak_rss_bytes().unwrap_or(0);
        let e = errors(&ds, &Surface::open(&out)?, &rule, &ignore, &ground_classes)?;
        let pct = |n: u64, of: u64| 100.0 * n as f64 / of.max(1) as f64;
        println!(
            "| {} | {:.3} | {} | {:.1} % | {:.2} % | {:.2} % | {:.2} % | {:.2} % | {:.3} | {seconds:.2} s | {} MB |",
            scan.file_name().unwrap_or_default().to_string_lossy(),
            p.cell,
            e.ground + e.other,
            pct(e.ground, e.ground + e.other),
            pct(e.type1, e.ground),
            pct(e.type2, e.other),
            100.0 * e.total(),
            pct(e.bare, e.ground + e.other),
            (e.ground_sq / e.ground_on.max(1) as f64).sqrt(),
            peak >> 20,
        );
        let _ = std::fs::remove_file(&out);
        let mut by: Vec<(u64, usize)> = (0..256)
            .map(|c| (e.type2_by_class[c], c))
            .filter(|x| x.0 > 0)
            .collect();
        by.sort_unstable_by(|a, b| b.cmp(a));
        let by: Vec<String> = by
            .iter()
            .take(4)
            .map(|(n, c)| format!("class {c}: {:.1} %", pct(*n, e.type2)))
            .collect();
        println!("type II by label: {}", by.join(", "));
    }
    let _ = std::fs::remove_dir_all(&scratch);
    Ok(())
}
