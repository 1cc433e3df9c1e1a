//! `myriad annotate PATH`: the saved work of a dataset, a scan or a folder of tiles (the
//! annotations and measurements `view` and `serve`'s web viewer keep in its sidecar,
//! `NAME.work.json` beside it): list, add, remove, import from and export to GeoJSON or DXF.

use anyhow::{Result, anyhow, bail};
use clap::Args;
use myriad_core::units::parse_floats;
use myriad_measure::files::{export_work, import_work, load_work, save_work};
use myriad_measure::measurement::Kind;
use myriad_measure::work::{self, Annotation, View, Work, sidecar_for};
use std::path::{Path, PathBuf};

#[derive(Args)]
pub struct AnnotateArgs {
    /// What the work belongs to: a dataset (.myr), a scan, or a folder of tiles, as given to
    /// `view` and `serve` (the work is kept beside it as NAME.work.json)
    path: PathBuf,
    /// Add an annotation at X,Y,Z (with --title, --text and --camera)
    #[arg(help_heading = "Adding", long, value_parser = parse_floats::<3>, allow_hyphen_values = true, value_name = "X,Y,Z")]
    add: Option<[f64; 3]>,
    /// With --add: its title
    #[arg(help_heading = "Adding", long, requires = "add", default_value = "")]
    title: String,
    /// With --add: its text
    #[arg(help_heading = "Adding", long, requires = "add", default_value = "")]
    text: String,
    /// With --add: the view it is shown from, EX,EY,EZ,TX,TY,TZ (eye and target)
    #[arg(help_heading = "Adding", long, requires = "add", value_parser = parse_floats::<6>, allow_hyphen_values = true)]
    camera: Option<[f64; 6]>,
    /// Add a measurement, KIND:X,Y,Z[,X,Y,Z...]: point, distance, height, area, angle, circle
    /// or azimuth through those points (repeatable)
    #[arg(
        help_heading = "Adding",
        long,
        value_name = "KIND:POINTS",
        allow_hyphen_values = true
    )]
    measure: Vec<String>,
    /// Remove the annotations of this title (repeatable)
    #[arg(help_heading = "Removing", long, value_name = "TITLE")]
    remove: Vec<String>,
    /// Remove every annotation and measurement first
    #[arg(help_heading = "Removing", long)]
    clear: bool,
    /// Add the annotations and measurements of a GeoJSON, DXF or work file (repeatable; its
    /// CRS must be the dataset's)
    #[arg(help_heading = "Import and export", long, value_name = "FILE")]
    import: Vec<PathBuf>,
    /// Write the work to a .geojson (the CRS named) or .dxf file
    #[arg(help_heading = "Import and export", long, value_name = "FILE")]
    export: Option<PathBuf>,
    /// Replace an existing --export file
    #[arg(long)]
    force: bool,
    /// Keep this class scheme with the work (a JSON file, as `render --classes-scheme` reads),
    /// for the viewers and `render`; `default`: none kept (the ASPRS table)
    #[arg(long, value_name = "FILE")]
    classes_scheme: Option<PathBuf>,
    /// Add a camera path from a file (as `render --path` reads; repeatable)
    #[arg(help_heading = "Import and export", long, value_name = "FILE")]
    add_path: Vec<PathBuf>,
    /// Write the camera path of this name (or number, from 1) to FILE: NAME=FILE
    #[arg(help_heading = "Import and export", long, value_name = "NAME=FILE")]
    export_path: Option<String>,
    /// Print the work as the sidecar's JSON instead of a list
    #[arg(long)]
    json: bool,
}

/// `KIND:X,Y,Z,...` as a measurement.
fn parse_measure(s: &str) -> Result<myriad_measure::measurement::Measurement> {
    let (kind, pts) = s
        .split_once(':')
        .ok_or_else(|| anyhow!("--measure {s}: KIND:X,Y,Z[,X,Y,Z...]"))?;
    let k = Kind::from_name(kind.trim()).ok_or_else(|| {
        let names: Vec<&str> = Kind::ALL.iter().map(|k| k.name()).collect();
        anyhow!(
            "--measure {s}: unknown measurement \"{kind}\" (one of {})",
            names.join(", ")
        )
    })?;
    let values = pts
        .split(',')
        .map(|v| {
            v.trim()
                .parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or_else(|| anyhow!("--measure {s}: \"{v}\" is not a number"))
        })
        .collect::<Result<Vec<f64>>>()?;
    if values.len() % 3 != 0 {
        bail!(
            "--measure {s}: {} numbers, not a list of X,Y,Z",
            values.len()
        );
    }
    let points = values.chunks(3).map(|c| [c[0], c[1], c[2]]).collect();
    work::measurement(k, points, &format!("--measure {s}")).map_err(|e| anyhow!(e))
}

fn list(w: &Work, sidecar: &Path) {
    let (units, metres) = work::units_of(w.crs.as_deref());
    let earth = myriad_measure::measurement::earth(w.crs.as_deref());
    let crs = w
        .crs
        .as_deref()
        .and_then(myriad_measure::geojson::epsg_code)
        .map_or(String::new(), |c| format!(", CRS EPSG:{c}"));
    println!(
        "{}: {} annotations, {} measurements{crs}",
        sidecar.display(),
        w.annotations.len(),
        w.measurements.len()
    );
    if let Some(s) = &w.classes {
        let changed: Vec<String> = (s.changed().iter())
            .map(|&c| {
                let [r, g, b] = s.colour(c);
                let hidden = if s.is_hidden(c) { ", hidden" } else { "" };
                format!("{c} {} #{r:02x}{g:02x}{b:02x}{hidden}", s.name(c))
            })
            .collect();
        println!("class scheme: {}", changed.join("; "));
    }
    for (i, p) in w.paths.iter().enumerate() {
        println!(
            "camera path {} \"{}\": {} views, {:.1} s",
            i + 1,
            p.name,
            p.keys.len(),
            p.duration()
        );
    }
    for (i, a) in w.annotations.iter().enumerate() {
        let p = a.position;
        let text = if a.text.is_empty() {
            String::new()
        } else {
            format!(": {}", a.text.replace('\n', " / "))
        };
        println!(
            "annotation {} \"{}\" at {:.3}, {:.3}, {:.3}{text}",
            i + 1,
            a.title,
            p[0],
            p[1],
            p[2]
        );
    }
    for (i, m) in w.measurements.iter().enumerate() {
        println!(
            "measurement {} {}: {} ({} points)",
            i + 1,
            m.kind.name(),
            m.label_for(units, metres, earth).unwrap_or_default(),
            m.points.len()
        );
    }
}

/// Imported work lies where the dataset does (within its own size around it): a file in other
/// coordinates (longitude and latitude, another projection, feet for metres) is refused even
/// where the two CRSs cannot be compared by EPSG code.
fn near_the_data(w: &myriad_measure::work::Work, b: &myriad_core::Aabb) -> Result<()> {
    let s = b.size();
    let margin = s[0].max(s[1]).max(s[2]).max(1.0);
    let points = (w.annotations.iter().map(|a| a.position))
        .chain(w.measurements.iter().flat_map(|m| m.points.iter().copied()));
    for p in points {
        let out = (0..2).any(|i| p[i] < b.min[i] - margin || p[i] > b.max[i] + margin);
        if out {
            bail!(
                "its point {:.3}, {:.3} lies far outside the dataset ({:.3}, {:.3} to {:.3}, {:.3}): \
                 another coordinate system? reproject it first",
                p[0],
                p[1],
                b.min[0],
                b.min[1],
                b.max[0],
                b.max[1]
            );
        }
    }
    Ok(())
}

pub fn run(a: AnnotateArgs) -> Result<()> {
    if myriad_format::remote::is_url(&a.path) {
        bail!(
            "{}: the work of a served dataset is kept by its server (serve --edit)",
            a.path.display()
        );
    }
    if !a.path.exists() {
        bail!("{}: no such file or folder", a.path.display());
    }
    let sidecar = sidecar_for(&a.path);
    let crs = myriad_build::open::crs_of(&a.path)?;
    let mut w = load_work(&sidecar, crs.as_deref())?;
    let before = w.clone();
    if a.clear {
        w.annotations.clear();
        w.measurements.clear();
    }
    for t in &a.remove {
        let n = w.annotations.len();
        w.annotations.retain(|x| &x.title != t);
        if w.annotations.len() == n {
            bail!("--remove \"{t}\": no annotation of that title");
        }
    }
    let bounds = myriad_build::open::bounds_of(&a.path)?;
    for f in &a.import {
        let other = import_work(f)?;
        if let Some(b) = bounds {
            near_the_data(&other, &b).map_err(|e| anyhow!("{}: {e}", f.display()))?;
        }
        w.merge(other)
            .map_err(|e| anyhow!("{}: {e}", f.display()))?;
    }
    if let Some(p) = a.add {
        if a.title.chars().count() > work::MAX_TITLE || a.text.chars().count() > work::MAX_TEXT {
            bail!(
                "--title: at most {} characters, --text: {}",
                work::MAX_TITLE,
                work::MAX_TEXT
            );
        }
        w.annotations.push(Annotation {
            position: p,
            title: a.title.clone(),
            text: a.text.clone(),
            camera: a.camera.map(|c| View {
                position: [c[0], c[1], c[2]],
                target: [c[3], c[4], c[5]],
            }),
        });
    }
    for m in &a.measure {
        w.measurements.push(parse_measure(m)?);
    }
    match a.classes_scheme.as_deref() {
        Some(f) if f.as_os_str() == "default" => w.classes = None,
        Some(f) => w.classes = Some(crate::measure::read_scheme(f)?),
        None => {}
    }
    for f in &a.add_path {
        w.paths.push(crate::render::read_path(f)?);
    }
    if w.paths.len() > work::MAX_ITEMS {
        bail!("more than {} camera paths", work::MAX_ITEMS);
    }
    if w.annotations.len() > work::MAX_ITEMS || w.measurements.len() > work::MAX_ITEMS {
        bail!("more than {} annotations or measurements", work::MAX_ITEMS);
    }
    if w != before {
        save_work(&sidecar, &w)?;
    }
    if let Some(out) = &a.export {
        myriad_io::atomic::refuse_input_as_output(out, &[&a.path, &sidecar])?;
        export_work(&w, out, a.force)?;
        eprintln!("{}: written", out.display());
    }
    if let Some(e) = &a.export_path {
        let (name, out) = e
            .rsplit_once('=')
            .ok_or_else(|| anyhow!("--export-path {e}: NAME=FILE"))?;
        let path =
            crate::render::saved_path(&w, name).map_err(|m| anyhow!("--export-path {e}: {m}"))?;
        let out = Path::new(out);
        myriad_io::atomic::refuse_input_as_output(out, &[&a.path, &sidecar])?;
        let text = path.to_file();
        myriad_measure::files::write_atomic(out, a.force, |w| w.write_all(text.as_bytes()))?;
        eprintln!("{}: written", out.display());
    }
    if a.json {
        print!("{}", w.to_text());
    } else {
        list(&w, &sidecar);
    }
    Ok(())
}
