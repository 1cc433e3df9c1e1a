//! `myriad classify DATASET`: reclassify or remove the points in a region, kept as edits beside
//! the dataset (`myriad_measure::edits`) and applied by every command that reads its points;
//! `--list`, `--undo`, `--redo`; `--apply -o OUT.myr` writes a dataset with them.

use anyhow::{Result, anyhow, bail};
use clap::Args;
use myriad_core::units::thousands;
use myriad_format::Dataset;
use myriad_measure::edits::{self, Action, Area, Change, Edit};
use myriad_measure::files::{check_shape, xy_arg};
use myriad_measure::filter::Filter;
use myriad_measure::shape::Want;
use std::path::{Path, PathBuf};

#[derive(Args)]
pub struct ClassifyArgs {
    /// The dataset (a .myr, COPC, EPT or Potree 2.0 dataset; convert a scan first)
    pub dataset: PathBuf,
    /// The points in a polygon in plan: X1,Y1,X2,Y2,X3,Y3[,...] in the dataset's coordinates,
    /// or @FILE (GeoJSON, WKT, CSV)
    #[arg(help_heading = "Region", long, allow_hyphen_values = true, conflicts_with_all = ["bbox", "corridor", "brush"])]
    polygon: Option<String>,
    /// With --polygon: only points between these elevations
    #[arg(help_heading = "Region", long, value_name = "Z0,Z1", requires = "polygon", value_parser = myriad_core::units::parse_floats::<2>, allow_hyphen_values = true)]
    z: Option<[f64; 2]>,
    /// The points in a box: X0,Y0,Z0,X1,Y1,Z1
    #[arg(help_heading = "Region", long = "box", value_name = "X0,Y0,Z0,X1,Y1,Z1", value_parser = myriad_core::units::parse_floats::<6>, allow_hyphen_values = true, conflicts_with_all = ["corridor", "brush"])]
    bbox: Option<[f64; 6]>,
    /// The points within half --width of a line in plan: X1,Y1,X2,Y2[,...] or @FILE
    #[arg(
        help_heading = "Region",
        long,
        allow_hyphen_values = true,
        requires = "width",
        conflicts_with = "brush"
    )]
    corridor: Option<String>,
    /// The corridor's width
    #[arg(help_heading = "Region", long)]
    width: Option<f64>,
    /// The points within spheres a brush painted: X,Y,Z,RADIUS[,X,Y,Z,RADIUS...]
    #[arg(help_heading = "Region", long, allow_hyphen_values = true)]
    brush: Option<String>,
    /// Only points of these classes: 2,6 or ground,building or 3-5
    #[arg(help_heading = "Filter", long, value_name = "LIST")]
    classes: Option<String>,
    /// Only points where these hold: "intensity>100", "z<350 and return_number==1"; may be given again
    #[arg(
        help_heading = "Filter",
        long = "where",
        value_name = "CONDITIONS",
        allow_hyphen_values = true
    )]
    wheres: Vec<String>,
    /// Give the points this class (a number 0-255 or a name: ground, noise, building...)
    #[arg(
        help_heading = "Edit",
        long,
        value_name = "CLASS",
        conflicts_with = "remove"
    )]
    to: Option<String>,
    /// Remove the points
    #[arg(help_heading = "Edit", long)]
    remove: bool,
    /// Do not count the points the edit changes (a read of the region's pages)
    #[arg(help_heading = "Edit", long)]
    no_count: bool,
    /// List the dataset's edits
    #[arg(help_heading = "Layer", long, conflicts_with_all = ["undo", "redo", "apply", "to", "remove"])]
    list: bool,
    /// Undo the last edit
    #[arg(help_heading = "Layer", long, conflicts_with_all = ["redo", "apply", "to", "remove"])]
    undo: bool,
    /// Redo the last edit undone
    #[arg(help_heading = "Layer", long, conflicts_with_all = ["apply", "to", "remove"])]
    redo: bool,
    /// Write a new dataset with the edits in its points (-o)
    #[arg(help_heading = "Layer", long, requires = "output", conflicts_with_all = ["to", "remove"])]
    apply: bool,
    /// With --apply: the dataset to write (.myr)
    #[arg(help_heading = "Layer", short, long)]
    output: Option<PathBuf>,
    /// With --apply: replace an existing output
    #[arg(help_heading = "Layer", long)]
    force: bool,
}

pub fn run(a: ClassifyArgs) -> Result<()> {
    if myriad_format::remote::is_url(&a.dataset) {
        bail!(
            "{}: edits are kept beside a dataset on this machine's disk; download it (or serve it \
             from here with `myriad serve`) to edit it",
            a.dataset.display()
        );
    }
    let dataset = edited_dataset(&a.dataset)?;
    let sidecar = edits::sidecar_for(&dataset);
    if a.apply {
        return apply(&a, &dataset);
    }
    if a.list {
        let layer = edits::read(&sidecar)?.unwrap_or_default();
        if layer.edits.is_empty() {
            println!("{}: no edits", dataset.display());
        }
        for (i, e) in layer.edits.iter().enumerate() {
            println!("{}: {}", i + 1, e.describe());
        }
        if !layer.undone.is_empty() {
            println!(
                "({} undone, --redo gives back the last)",
                layer.undone.len()
            );
        }
        return Ok(());
    }
    if a.undo || a.redo {
        let ds = Dataset::open_stored(&dataset)?;
        let asked = if a.undo { Change::Undo } else { Change::Redo };
        let (layer, done) = asked
            .apply(&dataset, &ds.meta)
            .map_err(|r| anyhow!(r.to_string()))?;
        println!(
            "{done} ({} edits in {})",
            layer.edits.len(),
            sidecar.display()
        );
        return Ok(());
    }
    let action = match (&a.to, a.remove) {
        (Some(c), false) => {
            let c = Filter::parse_classes(c).map_err(|m| anyhow!("--to {m}"))?;
            match c[..] {
                [one] => Action::Class(one),
                _ => bail!("--to: one class, not {}", c.len()),
            }
        }
        (None, true) => Action::Remove,
        _ => bail!(
            "say what to do: --to CLASS or --remove (or --list, --undo, --redo, --apply -o OUT)"
        ),
    };
    let ds = Dataset::open(&dataset)?;
    let edit = Edit {
        area: area(&a, &ds)?,
        classes: a.classes.clone(),
        wheres: a.wheres.clone(),
        action,
    };
    // What it would fail on when read, it fails on now.
    edits::admit(&edit, &ds.meta, &sidecar).map_err(|m| anyhow!("{}: {m}", dataset.display()))?;
    let counted = if a.no_count {
        None
    } else {
        Some(count(&ds, &edit)?)
    };
    // The file as it is now, held while it changes (another command may have changed it
    // since it was read, or be about to).
    let (layer, _) = Change::Add(edit.clone())
        .apply(&dataset, &ds.meta)
        .map_err(|r| anyhow!(r.to_string()))?;
    let what = match counted {
        None => String::new(),
        Some((n, changed)) => match edit.action {
            Action::Remove | Action::Ground { .. } => format!(": {} points removed", thousands(n)),
            Action::Class(c) => format!(
                ": {} points selected, {} of them given class {c}",
                thousands(n),
                thousands(changed)
            ),
        },
    };
    println!(
        "edit {} kept in {} ({}){what}",
        layer.edits.len(),
        sidecar.display(),
        edit.describe()
    );
    Ok(())
}

/// The dataset edits are kept beside: a dataset, not a scan (a scan's dataset is rebuilt, under
/// another name, when the scan changes: edits kept beside it would be left behind).
pub(crate) fn edited_dataset(input: &Path) -> Result<PathBuf> {
    if !myriad_format::is_dataset(input) {
        bail!(
            "{}: not a dataset: convert it first (`myriad convert {} -o NAME.myr`) so that its \
             edits have a dataset to stay beside",
            input.display(),
            input.display()
        );
    }
    Ok(input.to_path_buf())
}

/// The region the options give (everywhere when none).
fn area(a: &ClassifyArgs, ds: &Dataset) -> Result<Area> {
    let crs = ds.meta.crs.as_deref();
    let bounds = &ds.meta.bounds;
    if let Some(p) = &a.polygon {
        let s = xy_arg(p, "--polygon", Want::Polygon).map_err(|e| anyhow!(e))?;
        check_shape(&s, p, "--polygon", crs, bounds).map_err(|e| anyhow!(e))?;
        if let Some(z) = a.z
            && z[0] > z[1]
        {
            bail!("--z {},{}: the first is above the second", z[0], z[1]);
        }
        return Ok(Area::Polygon {
            ring: s.points,
            z: a.z,
        });
    }
    if let Some(b) = a.bbox {
        if (0..3).any(|i| b[i] > b[i + 3]) {
            bail!("--box: X0,Y0,Z0 must be the lowest corner, X1,Y1,Z1 the highest");
        }
        return Ok(Area::Box(myriad_core::Aabb::new(
            [b[0], b[1], b[2]],
            [b[3], b[4], b[5]],
        )));
    }
    if let Some(l) = &a.corridor {
        let s = xy_arg(l, "--corridor", Want::Line).map_err(|e| anyhow!(e))?;
        check_shape(&s, l, "--corridor", crs, bounds).map_err(|e| anyhow!(e))?;
        return Ok(Area::Corridor {
            line: s.points,
            width: a.width.unwrap_or(0.0),
        });
    }
    if let Some(b) = &a.brush {
        let v = (b.split(','))
            .map(|t| t.trim().parse::<f64>().ok().filter(|x| x.is_finite()))
            .collect::<Option<Vec<f64>>>()
            .filter(|v| !v.is_empty() && v.len() % 4 == 0)
            .ok_or_else(|| anyhow!("--brush \"{b}\": numbers X,Y,Z,RADIUS, four per sphere"))?;
        return Ok(Area::Brush(
            v.chunks(4).map(|c| [c[0], c[1], c[2], c[3]]).collect(),
        ));
    }
    Ok(Area::All)
}

/// The points `e` selects in `ds` (its edits so far applied), and those of them it changes.
fn count(ds: &Dataset, e: &Edit) -> Result<(u64, u64)> {
    let region: Box<dyn myriad_measure::Region> = match e.region().map_err(|m| anyhow!(m))? {
        Some(r) => r,
        None => Box::new(ds.meta.root),
    };
    let bound = (e.filter())
        .and_then(|f| f.bind(&ds.meta.schema))
        .map_err(|m| anyhow!(m))?;
    let (mut n, mut changed) = (0u64, 0u64);
    myriad_measure::read_region(ds, region.as_ref(), &bound, |b| {
        n += b.len() as u64;
        changed += match (&e.action, &b.classification) {
            (Action::Class(c), Some(cl)) => cl.iter().filter(|&&x| x != *c).count() as u64,
            _ => b.len() as u64,
        };
    })
    .map_err(|m| anyhow!(m))?;
    Ok((n, changed))
}

fn apply(a: &ClassifyArgs, dataset: &Path) -> Result<()> {
    let out = a.output.as_ref().expect("clap: --apply requires -o");
    let ds = Dataset::open(dataset)?;
    let t = std::time::Instant::now();
    let bar = crate::progress::Bar::new();
    let done = myriad_build::edited::apply(&ds, out, a.force, &bar);
    bar.clear();
    let w = done?;
    println!(
        "{}: {} points in {} nodes ({} edited, {} points removed), {} bytes, {:.2} s",
        out.display(),
        thousands(w.points),
        thousands(w.nodes),
        thousands(w.edited),
        thousands(w.removed),
        thousands(w.bytes),
        t.elapsed().as_secs_f64()
    );
    Ok(())
}
