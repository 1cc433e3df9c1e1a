//! `myriad ground DATASET`: the terrain under a dataset found out of core (SMRF in tiles with
//! overlap, `myriad_measure::ground`), kept beside it as a surface and an edit that classifies
//! its points against it: ground (2), low or isolated noise (7), and not ground (1) for points
//! labelled 2.

use anyhow::{Result, anyhow, bail};
use clap::Args;
use myriad_core::units::thousands;
use myriad_format::Dataset;
use myriad_measure::edits::{self, Action, Area, Edit};
use myriad_measure::ground;
use std::path::{Path, PathBuf};

#[derive(Args)]
pub struct GroundArgs {
    /// The dataset (a .myr, COPC, EPT or Potree 2.0 dataset; convert a scan first)
    pub dataset: PathBuf,
    /// The terrain grid's cell, in the dataset's units [default: --spacings times the points'
    /// mean spacing in plan]
    #[arg(long)]
    cell: Option<f64>,
    /// Without --cell: a cell of this many mean spacings (more where little reaches the ground)
    #[arg(long, default_value_t = 2.5)]
    spacings: f64,
    /// The terrain's steepest slope, rise over run (0.15: 15 %)
    #[arg(long, default_value_t = 0.15)]
    slope: f64,
    /// The largest window's radius, in metres: about half the widest building (lengths are in
    /// metres, converted through the dataset's CRS; a dataset without one is taken in metres)
    #[arg(long, default_value_t = 30.0)]
    window: f64,
    /// How far the terrain reaches from the cells that hold ground, in metres (under wider
    /// buildings and gaps it has none: their points keep their classes)
    #[arg(long, default_value_t = 64.0)]
    fill: f64,
    /// A point within this height of the terrain, in metres, is ground...
    #[arg(long, default_value_t = 0.5)]
    threshold: f64,
    /// ...plus this much per unit of the terrain's slope
    #[arg(long, default_value_t = 1.25)]
    scalar: f64,
    /// A point this much (metres) further below the terrain is low noise (class 7); a cell
    /// this much below its neighbours' closing is left out of the terrain
    #[arg(long, default_value_t = 1.0)]
    low: f64,
    /// A point with fewer than this many others in the 3 x 3 x 3 cubes of a cell around it is
    /// isolated noise (class 7); 0: none looked for
    #[arg(long, default_value_t = 2)]
    isolated: usize,
    /// Memory for the tiles in flight (the points are read page by page)
    #[arg(long, value_parser = myriad_build::convert::parse_size, default_value = "1GB")]
    memory: u64,
    /// A tile's side in cells [default: from --memory and the cores]
    #[arg(long)]
    tile: Option<usize>,
    /// Do not count the classes given (a read of every page)
    #[arg(long)]
    no_count: bool,
}

pub fn run(a: GroundArgs) -> Result<()> {
    if myriad_format::remote::is_url(&a.dataset) {
        bail!(
            "{}: the terrain and its edit are kept beside a dataset on this machine's disk; \
             download it to classify its ground",
            a.dataset.display()
        );
    }
    for (name, v) in [
        ("--cell", a.cell.unwrap_or(1.0)),
        ("--spacings", a.spacings),
        ("--window", a.window),
        ("--fill", a.fill),
    ] {
        if !(v.is_finite() && v > 0.0) {
            bail!("{name} {v}: a positive number");
        }
    }
    for (name, v) in [
        ("--slope", a.slope),
        ("--threshold", a.threshold),
        ("--scalar", a.scalar),
        ("--low", a.low),
    ] {
        if !(v.is_finite() && v >= 0.0) {
            bail!("{name} {v}: a number 0 or more");
        }
    }
    let options = ground::Options {
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
    let dataset = crate::classify::edited_dataset(&a.dataset)?;
    let sidecar = edits::sidecar_for(&dataset);
    let ds = Dataset::open(&dataset)?;
    if !ds.meta.schema.has(&myriad_core::Attribute::Classification) {
        bail!("{}: the dataset has no classes to set", dataset.display());
    }
    let (p, rule) = options.resolve(ds.meta.points, &ds.meta.bounds, ds.meta.crs.as_deref());
    if p.window > 4096 || p.fill > 4096 {
        bail!(
            "--window and --fill: at most 4,096 cells of {} (a larger --cell)",
            p.cell
        );
    }
    let threads = rayon::current_num_threads();
    let tile = match a.tile {
        Some(t) => t,
        None => ground::tile_for(a.memory, threads, &p, a.isolated > 0)?,
    };
    if tile == 0 || tile > ground::surface::MAX_TILE {
        bail!(
            "--tile {tile}: from 1 to {} cells",
            ground::surface::MAX_TILE
        );
    }
    let surface = free_name(&dataset);
    let t = std::time::Instant::now();
    let bar = crate::progress::Bar::new();
    let made = ground::build(&ds, &p, a.isolated, tile, &surface, &|_, _| {});
    bar.clear();
    let made = made?;
    let seconds = t.elapsed().as_secs_f64();
    let name = surface
        .file_name()
        .expect("a file")
        .to_string_lossy()
        .into_owned();
    let edit = Edit {
        area: Area::All,
        classes: None,
        wheres: Vec::new(),
        action: Action::Ground {
            surface: name.clone(),
            rule,
        },
    };
    // The file as it is now: edits made while the terrain was being made are kept.
    let crs = ds.meta.crs.clone();
    let (layer, _) = edits::change(&sidecar, |layer| {
        layer.crs = crs;
        layer.push(edit);
        Ok(())
    })
    .map_err(|m| anyhow!(m))?;
    let pl = made.placement;
    println!(
        "terrain: {} x {} cells of {} in {} tiles of {tile}, {} points read, {} bytes in {name}, {seconds:.2} s",
        thousands(pl.nx as u64),
        thousands(pl.ny as u64),
        pl.cell,
        made.tiles,
        thousands(made.points_read),
        thousands(made.bytes),
    );
    println!(
        "edit {} kept in {} (ground against {name})",
        layer.edits.len(),
        sidecar.display()
    );
    if !a.no_count {
        let ds = Dataset::open(&dataset)?;
        let mut counts = [0u64; 256];
        myriad_measure::read_region(&ds, &ds.meta.root, &myriad_measure::Bound::all(), |b| {
            for &c in b.classification.as_deref().unwrap_or(&[]) {
                counts[c as usize] += 1;
            }
        })
        .map_err(anyhow::Error::msg)?;
        let all: u64 = counts.iter().sum();
        println!(
            "{} points: {} ground (class 2, {:.1} %), {} noise (class 7: low or isolated)",
            thousands(all),
            thousands(counts[2]),
            100.0 * counts[2] as f64 / all.max(1) as f64,
            thousands(counts[7])
        );
    }
    println!(
        "peak memory {} MB",
        myriad_io::process::peak_rss_bytes().unwrap_or(0) >> 20
    );
    Ok(())
}

/// `city.ground-N.surface` beside the dataset, the first N not taken (an undone ground edit's
/// surface stays, for redo).
fn free_name(dataset: &Path) -> PathBuf {
    let sidecar = edits::sidecar_for(dataset);
    let stem = sidecar
        .file_name()
        .expect("a file")
        .to_string_lossy()
        .trim_end_matches(".edits.json")
        .to_string();
    (1..)
        .map(|n| sidecar.with_file_name(format!("{stem}.ground-{n}.surface")))
        .find(|p| !p.exists())
        .expect("a free name")
}
