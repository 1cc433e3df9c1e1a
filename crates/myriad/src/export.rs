//! `myriad export`: a dataset as COPC, Potree 2.0, 3D Tiles, LAS or LAZ, or the web viewer as a
//! static site opening it (`--to web`).

use anyhow::{Result, bail};
use clap::Args;
use myriad_build::export::{self, ExportOptions, Target};
use myriad_core::Aabb;
use myriad_format::Dataset;
use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::dataset::parse_box;
use crate::progress::Bar;
use myriad_core::units::thousands;

#[derive(Args)]
pub struct ExportArgs {
    /// The dataset (.myr)
    dataset: PathBuf,
    /// Output: a .copc.laz file (COPC), a folder (Potree 2.0, or 3D Tiles with --to 3dtiles),
    /// or a .las/.laz file
    #[arg(short, long)]
    output: PathBuf,
    /// Format: copc, potree, 3dtiles, las or laz [default: from the output's name]; or web: a
    /// folder any static web server serves, the web viewer opening the dataset (copied in) and
    /// those --add names
    #[arg(long = "to", value_parser = parse_to)]
    target: Option<To>,
    /// --to web: another dataset the site opens (a URL, on this host or another that sends
    /// CORS headers; or a .myr, COPC, EPT or Potree 2.0 here, linked in); may be given again
    #[arg(long, value_name = "DATASET")]
    add: Vec<PathBuf>,
    /// Replace an existing output (a folder only when it holds a Potree or 3D Tiles export)
    #[arg(long)]
    force: bool,
    /// Only points in this box: minx,miny,minz,maxx,maxy,maxz
    #[arg(help_heading = "Selection", long = "box", value_parser = parse_box, allow_hyphen_values = true)]
    bbox: Option<Aabb>,
    /// Level of detail: points at about this spacing [default: every original point]
    #[arg(help_heading = "Selection", long)]
    spacing: Option<f64>,
    /// Memory budget of the octree build that kd and mwkd datasets go through: 512MB, 2GB
    #[arg(long, value_parser = myriad_build::convert::parse_size)]
    memory: Option<u64>,
    #[command(flatten, next_help_heading = "Selection")]
    filter: crate::measure::FilterArgs,
    /// Move the points into this coordinate system (EPSG:NNNN, EPSG:H+V, WKT or a PROJ string):
    /// they are re-placed into an octree of the new coordinates first
    #[arg(help_heading = "Coordinates", long, value_name = "CRS")]
    to_crs: Option<String>,
    /// The dataset's coordinate system where it names none (with --to-crs or --to 3dtiles)
    #[arg(help_heading = "Coordinates", long, value_name = "CRS")]
    from_crs: Option<String>,
    /// 3D Tiles version: 1.1 (glTF tiles) or 1.0 (.pnts tiles, for older clients)
    #[arg(help_heading = "3D Tiles", long, value_name = "VERSION", default_value = "1.1", value_parser = myriad_io::tiles3d::Version::parse)]
    tiles_version: myriad_io::tiles3d::Version,
    /// COPC: a parent whose children are all leaves takes their points where they hold at most
    /// this many times the dataset's node capacity together (0: node for node, the largest
    /// file) [default: 3]
    #[arg(help_heading = "COPC", long, value_name = "TIMES", value_parser = parse_join)]
    copc_join: Option<f64>,
}

fn parse_join(s: &str) -> std::result::Result<f64, String> {
    match s.parse::<f64>() {
        Ok(x) if (0.0..=64.0).contains(&x) => Ok(x),
        _ => Err(format!("\"{s}\": expected a number from 0 to 64")),
    }
}

/// What `--to` names: a format the points are written in, or the web viewer's static site.
#[derive(Clone, Copy, PartialEq, Debug)]
enum To {
    Points(Target),
    Web,
}

fn parse_to(s: &str) -> std::result::Result<To, String> {
    match s.eq_ignore_ascii_case("web") {
        true => Ok(To::Web),
        false => Target::parse(s)
            .map(To::Points)
            .map_err(|_| format!("\"{s}\": expected copc, potree, 3dtiles, las, laz or web")),
    }
}

pub fn run(a: ExportArgs) -> Result<()> {
    if a.spacing.is_some_and(|s| !(s.is_finite() && s > 0.0)) {
        bail!("--spacing must be a positive length");
    }
    if a.target == Some(To::Web) {
        return web(&a);
    }
    if !a.add.is_empty() {
        bail!("--add goes with --to web");
    }
    let target = a.target.map(|t| match t {
        To::Points(t) => t,
        To::Web => unreachable!("handled above"),
    });
    let Some(target) = target.or_else(|| Target::from_output(&a.output)) else {
        bail!(
            "{}: cannot tell the format from the name; give --to copc|potree|3dtiles|las|laz",
            a.output.display()
        );
    };
    if a.from_crs.is_some() && a.to_crs.is_none() && target != Target::Tiles {
        bail!("--from-crs goes with --to-crs or --to 3dtiles");
    }
    myriad_io::atomic::refuse_input_as_output(&a.output, &[&a.dataset])?;
    let ds = Dataset::open(&a.dataset)?;
    let o = export_options(&a, target)?;
    let bar = Bar::new();
    let t = Instant::now();
    let s = export::export(&ds, &a.output, &o, &bar)?;
    bar.clear();
    let secs = t.elapsed().as_secs_f64();
    for d in &s.damage {
        eprintln!("warning: {}", ds.damage_error(d));
    }
    for l in &s.not_kept {
        eprintln!("warning: not kept: {l}");
    }
    print_exported(&a, target, &ds, &s, secs);
    if let Some(d) = s.damage.first() {
        bail!(
            "{} ({} damaged page{} left out; {} lacks node{} {})",
            ds.damage_error(d),
            s.damage.len(),
            if s.damage.len() == 1 { "" } else { "s" },
            a.output.display(),
            if s.damage.len() == 1 { "" } else { "s" },
            s.damage
                .iter()
                .map(|d| format!(
                    "{}-{}-{}-{}",
                    d.key.level, d.key.cell[0], d.key.cell[1], d.key.cell[2]
                ))
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    Ok(())
}

/// `--to web`: the web viewer as a static site in the folder `a.output`, opening the dataset
/// and those `--add` names (a URL as it is; a local `.myr` hard-linked or copied into `data/`).
fn web(a: &ExportArgs) -> Result<()> {
    if a.bbox.is_some() || a.spacing.is_some() || a.to_crs.is_some() || {
        let f = a.filter.filter()?;
        f.classes.is_some() || !f.conditions.is_empty()
    } {
        bail!(
            "--to web writes the viewer and the datasets as they are: no --box, --spacing, --to-crs or filter"
        );
    }
    let inputs: Vec<&PathBuf> = std::iter::once(&a.dataset).chain(&a.add).collect();
    let locals: Vec<&PathBuf> = (inputs.iter().copied())
        .filter(|p| !myriad_format::remote::is_url(p))
        .collect();
    myriad_io::atomic::refuse_input_as_output(&a.output, &locals)?;
    let dir = myriad_io::atomic::AtomicDir::create(
        &a.output,
        a.force,
        myriad_serve::viewer::is_site,
        "a web export",
    )?;
    let data = dir.temp().join("data");
    let mut urls = Vec::new();
    let mut copied = 0u64;
    for p in inputs {
        let text = p.to_string_lossy();
        if myriad_format::remote::is_url(p) {
            if text.starts_with("s3://") {
                bail!(
                    "{text}: a browser reads http(s):// addresses (give the bucket's https:// URL)"
                );
            }
            urls.push(text.into_owned());
            continue;
        }
        let ds = Dataset::open(p)?;
        if !ds.files().is_empty() {
            bail!(
                "{text}: a dataset of several files: merge it into one first (merge --single-file)"
            );
        }
        if ds.meta.structure == "tiles" {
            bail!(
                "{text}: a set of tiles: the web viewer opens one COPC, EPT, Potree 2.0 or .myr dataset at a time (--add each)"
            );
        }
        // EPT and Potree 2.0 are folders (their document named, or the folder); the rest files.
        let document = match ds.foreign_format() {
            Some("EPT") => Some("ept.json"),
            Some("Potree 2.0") => Some("metadata.json"),
            _ => None,
        };
        let from = match document.is_some() && !p.is_dir() {
            true => p.parent().unwrap_or(Path::new(".")).to_path_buf(),
            false => p.clone(),
        };
        let name = std::fs::canonicalize(&from)
            .ok()
            .and_then(|c| c.file_name().map(|n| n.to_string_lossy().into_owned()))
            .unwrap_or_else(|| "dataset".into());
        std::fs::create_dir_all(&data)?;
        let mut to = data.join(&name);
        let mut i = 1;
        while to.exists() {
            to = data.join(format!("{i}-{name}"));
            i += 1;
        }
        copied += link_or_copy(&from, &to)?;
        let mut rel = to
            .strip_prefix(dir.temp())
            .expect("below the site")
            .to_path_buf();
        if let Some(d) = document {
            rel = rel.join(d);
        }
        urls.push(rel.to_string_lossy().replace('\\', "/"));
    }
    myriad_serve::viewer::write_site(dir.temp(), &urls)
        .map_err(|e| myriad_core::Error::io(dir.temp(), e))?;
    dir.commit()?;
    println!(
        "{}: the web viewer, opening {} ({:.1} MB of datasets in it): serve the folder from any \
         web server that answers range requests and open index.html",
        a.output.display(),
        urls.join(", "),
        copied as f64 / 1e6
    );
    Ok(())
}

/// `from` (a file, or a folder and everything below it) at `to`, each file hard-linked (costs
/// nothing; the original is never written through it, the site is read only) or, on another
/// file system, copied: the bytes it holds.
fn link_or_copy(from: &Path, to: &Path) -> Result<u64> {
    let meta = std::fs::metadata(from).map_err(|e| myriad_core::Error::io(from, e))?;
    if meta.is_dir() {
        std::fs::create_dir_all(to).map_err(|e| myriad_core::Error::io(to, e))?;
        let mut total = 0;
        for e in std::fs::read_dir(from).map_err(|e| myriad_core::Error::io(from, e))? {
            let e = e.map_err(|e| myriad_core::Error::io(from, e))?;
            total += link_or_copy(&e.path(), &to.join(e.file_name()))?;
        }
        return Ok(total);
    }
    if std::fs::hard_link(from, to).is_err() {
        std::fs::copy(from, to).map_err(|e| myriad_core::Error::io(from, e))?;
    }
    Ok(meta.len())
}

/// The export's options from the command line.
fn export_options(a: &ExportArgs, target: Target) -> Result<ExportOptions> {
    let mut o = ExportOptions::new(target);
    o.bbox = a.bbox;
    o.spacing = a.spacing;
    o.filter = a.filter.filter()?;
    o.force = a.force;
    o.reproject = a.to_crs.as_ref().map(|to| myriad_io::reproject::Reproject {
        to: to.clone(),
        from: a.from_crs.clone(),
    });
    o.from_crs = a.from_crs.clone();
    o.tiles_version = a.tiles_version;
    o.copc_join = a.copc_join;
    if let Some(m) = a.memory {
        o.memory = m;
    }
    Ok(o)
}

/// What the export wrote: points, nodes, tilesets or the structure re-placed, size, speed;
/// points left out; peak memory.
fn print_exported(
    a: &ExportArgs,
    target: Target,
    ds: &Dataset,
    s: &export::ExportSummary,
    secs: f64,
) {
    println!(
        "{}: {} points in {} nodes{}, {:.1} MB, {:.1} s ({:.2} M points/s)",
        a.output.display(),
        thousands(s.points),
        thousands(s.nodes),
        if let Some(to) = &a.to_crs {
            format!(" (moved into {to})")
        } else if target == Target::Tiles {
            format!(
                " ({} tileset file{}{})",
                s.tilesets,
                if s.tilesets == 1 { "" } else { "s" },
                if s.replaced {
                    format!(", re-placed from the {} structure", ds.meta.structure)
                } else {
                    String::new()
                }
            )
        } else if s.replaced {
            format!(
                " (re-placed from the {} structure into an octree)",
                ds.meta.structure
            )
        } else {
            String::new()
        },
        s.bytes as f64 / 1e6,
        secs,
        s.points as f64 / secs.max(1e-9) / 1e6
    );
    if s.not_transformed > 0 {
        eprintln!(
            "warning: {} points do not transform into {} (outside its domain, or a grid PROJ \
             lacks there): left out",
            thousands(s.not_transformed),
            a.to_crs
                .as_deref()
                .unwrap_or("Earth-centred coordinates (EPSG:4978)")
        );
    }
    if let Some(p) = myriad_io::process::peak_rss_bytes() {
        println!("peak resident memory: {:.0} MB", p as f64 / 1e6);
    }
}
