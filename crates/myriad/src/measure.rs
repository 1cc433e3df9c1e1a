//! `myriad profile` and `myriad volume`, and the filters (`--classes`, `--where`) that
//! `extract`, `export`, `render` and `profile` share.

use anyhow::{Result, anyhow, bail};
use clap::Args;
use myriad_build::extract::{self, ExtractOptions};
use myriad_core::colour::{ColorBy, Gradient};
use myriad_format::Dataset;
use myriad_measure::files::{check_shape, save_drawing, write_atomic, xy_arg};
use myriad_measure::shape::Want;
use myriad_measure::volume::{self, Base};
use myriad_measure::{Corridor, Filter, Polygon};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use myriad_core::units::thousands;

/// Which points a command keeps.
#[derive(Args, Clone, Default)]
pub struct FilterArgs {
    /// Only these ASPRS classes: numbers or names, as 2,6 or ground,building or 3-5
    #[arg(long, value_name = "LIST")]
    pub classes: Option<String>,
    /// Only points where these hold, as intensity>100, return_number=1, gps_time=1000..2000
    /// (conditions joined by commas or "and"; repeatable; `myriad info` lists the attributes)
    #[arg(long = "where", value_name = "CONDITIONS", allow_hyphen_values = true)]
    pub conditions: Vec<String>,
}

impl FilterArgs {
    pub fn filter(&self) -> Result<Filter> {
        Filter::parse(self.classes.as_deref(), &self.conditions).map_err(|e| anyhow!(e))
    }
}

/// What a point's colour shows.
#[derive(Args, Clone)]
pub struct ColourArgs {
    /// Colour: rgb, intensity, elevation, classification, return, source, level, uniform (one
    /// grey: the shape by shading alone), or any attribute (gps_time, scan_angle,
    /// point_source_id, an extra-bytes dimension by name) through --gradient, or above-ground
    /// (the height above the terrain `myriad ground` found)
    #[arg(long = "color", default_value = "rgb")]
    pub colour: String,
    /// A gradient for the colour's values: spectral, viridis, turbo, grey [default: viridis;
    /// spectral for elevation, turbo above the ground]
    #[arg(long, value_parser = parse_gradient)]
    pub gradient: Option<Gradient>,
    /// The values the gradient spans: LOW,HIGH [default: the 2nd to 98th percentile of the
    /// overview's; from 0 above the ground]
    #[arg(long, value_parser = myriad_core::units::parse_floats::<2>, allow_hyphen_values = true)]
    pub range: Option<[f64; 2]>,
    /// Class names, colours and classes hidden, from a JSON file ({"classes": {"2": {"name":
    /// "terrain", "colour": "#8b5a2b", "hidden": false}}}) [default: the one kept with the
    /// dataset's saved work (`myriad annotate --classes-scheme`), else the ASPRS table with
    /// noise (7, 18) hidden]
    #[arg(long, value_name = "FILE")]
    pub classes_scheme: Option<PathBuf>,
}

fn parse_gradient(s: &str) -> Result<Gradient, String> {
    Gradient::parse(s).ok_or_else(|| format!("\"{s}\": expected one of {}", Gradient::NAMES))
}

impl ColourArgs {
    /// The colour for a dataset of `schema` whose overview is `sample`.
    pub fn choose(
        &self,
        schema: &myriad_core::Schema,
        sample: impl FnOnce() -> myriad_core::PointBatch,
    ) -> Result<ColorBy> {
        if let Some([lo, hi]) = self.range
            && !(lo < hi)
        {
            bail!("--range {lo},{hi}: the low end must be below the high end");
        }
        myriad_core::colour::choose(&self.colour, self.gradient, self.range, schema, sample)
            .map_err(|e| anyhow!(e))
    }

    /// The class scheme for what `opened` names (`--classes-scheme`, else the one its saved
    /// work keeps, else the default), put in force for the colours made from now on.
    pub fn use_scheme(&self, opened: &Path) -> Result<myriad_core::classes::Scheme> {
        let scheme = match &self.classes_scheme {
            Some(f) => read_scheme(f)?,
            None => saved_scheme(opened),
        };
        myriad_core::classes::set(scheme.clone());
        Ok(scheme)
    }

    /// [`ColourArgs::choose`] for a dataset, fitted to its overview.
    pub fn for_dataset(&self, ds: &Dataset) -> Result<ColorBy> {
        if let Some([lo, hi]) = self.range
            && !(lo < hi)
        {
            bail!("--range {lo},{hi}: the low end must be below the high end");
        }
        (ds.choose_colour(&self.colour, self.gradient, self.range)).map_err(|e| anyhow!(e))
    }
}

#[derive(Args)]
pub struct ProfileArgs {
    /// The dataset (.myr, or its URL)
    dataset: PathBuf,
    /// The section line in plan: X1,Y1,X2,Y2[,X3,Y3...] in the dataset's coordinates, or
    /// @FILE: a LineString in GeoJSON or WKT, or a CSV of x,y vertices
    #[arg(long, allow_hyphen_values = true)]
    line: String,
    /// The corridor's width: points within half of it on either side of the line
    #[arg(long)]
    width: f64,
    /// Output: .csv (x, y, z, distance, offset, attributes), .las/.laz (the points as they
    /// are), .dxf (the profile line, the points, the section line), .png (the profile drawn)
    /// or .geojson (the section line and its figures)
    #[arg(short, long)]
    output: PathBuf,
    #[command(flatten)]
    filter: FilterArgs,
    #[command(flatten)]
    colour: ColourArgs,
    /// Width of a .png in pixels
    #[arg(long, default_value_t = 1600)]
    pixels: u32,
    /// Replace an existing output
    #[arg(long)]
    force: bool,
}

fn extension(p: &Path) -> String {
    p.extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default()
}

pub fn profile(a: ProfileArgs) -> Result<()> {
    let line = xy_arg(&a.line, "--line", Want::Line).map_err(|e| anyhow!(e))?;
    let corridor = Corridor::new(&line.points, a.width).map_err(|e| anyhow!(e))?;
    let filter = a.filter.filter()?;
    a.colour.use_scheme(&a.dataset)?;
    let ext = extension(&a.output);
    if !matches!(
        ext.as_str(),
        "csv" | "las" | "laz" | "dxf" | "png" | "geojson"
    ) {
        bail!(
            "{}: profile writes .csv, .las, .laz, .dxf, .png or .geojson",
            a.output.display()
        );
    }
    if !(64..=16384).contains(&a.pixels) {
        bail!("--pixels {}: between 64 and 16384", a.pixels);
    }
    myriad_io::atomic::refuse_input_as_output(&a.output, &[&a.dataset])?;
    let ds = Dataset::open(&a.dataset)?;
    check_shape(
        &line,
        &a.line,
        "--line",
        ds.meta.crs.as_deref(),
        &ds.meta.bounds,
    )
    .map_err(|e| anyhow!(e))?;
    let u = units_of(&ds);
    let start = Instant::now();
    if matches!(ext.as_str(), "las" | "laz") {
        return profile_points(&a, &ds, &corridor, filter, start);
    }
    let bound = filter.bind(&ds.meta.schema).map_err(|e| anyhow!(e))?;
    let colour = a.colour.for_dataset(&ds)?;
    let p =
        myriad_measure::profile::profile(&ds, &corridor, &bound, colour).map_err(|e| anyhow!(e))?;
    write_profile(&a, &ext, &ds, &corridor, &p)?;
    let (z0, z1) = p.z_range();
    println!(
        "{}: {} points within {} {u} of a {:.3} {u} line (elevation {z0:.3} to {z1:.3}), from {} nodes, {:.2} s",
        a.output.display(),
        thousands(p.len() as u64),
        a.width / 2.0,
        corridor.length(),
        thousands(p.nodes_read),
        start.elapsed().as_secs_f64()
    );
    if p.is_empty() {
        println!("the corridor holds no point: the file has no rows");
    }
    Ok(())
}

/// `profile -o CUT.las|laz`: the corridor's original points, as `extract` writes them.
fn profile_points(
    a: &ProfileArgs,
    ds: &Dataset,
    corridor: &Corridor,
    filter: myriad_measure::Filter,
    start: Instant,
) -> Result<()> {
    let u = units_of(ds);
    let s = extract::extract(
        ds,
        &a.output,
        &ExtractOptions {
            region: Some(Arc::new(corridor.clone())),
            filter,
            force: a.force,
            ..Default::default()
        },
    )?;
    if let Some(d) = s.damage.first() {
        bail!("{} (the profile would lack its points)", ds.damage_error(d));
    }
    println!(
        "{}: {} points within {} {u} of a {:.3} {u} line, from {} nodes, {:.2} s",
        a.output.display(),
        thousands(s.points),
        a.width / 2.0,
        corridor.length(),
        thousands(s.nodes_read),
        start.elapsed().as_secs_f64()
    );
    if s.points == 0 {
        println!("the corridor holds no point: the file is empty");
    }
    Ok(())
}

/// The profile `p` written as the output's extension `ext` says: CSV rows, GeoJSON (the line
/// and the profile's top line), a DXF drawing, or a PNG plot.
fn write_profile(
    a: &ProfileArgs,
    ext: &str,
    ds: &Dataset,
    corridor: &Corridor,
    p: &myriad_measure::profile::Profile,
) -> Result<()> {
    match ext {
        "csv" => write_atomic(&a.output, a.force, |w| p.write_csv(w))?,
        "geojson" => {
            use myriad_measure::geojson::{collection, feature, line_geometry};
            let (z0, z1) = p.z_range();
            let f = feature(
                line_geometry(corridor.line()),
                serde_json::json!({
                    "dataset": a.dataset.display().to_string(), "length": corridor.length(),
                    "width": corridor.width(), "points": p.len(),
                    "z_min": z0, "z_max": z1, "units": units_of(ds),
                    // The profile line: (distance along, elevation), the highest point per
                    // half-width step.
                    "profile": p.top_line((p.width / 2.0).max(1e-3)),
                }),
            );
            let doc = collection(vec![f], ds.meta.crs.as_deref());
            write_atomic(&a.output, a.force, |w| {
                serde_json::to_writer_pretty(&mut *w, &doc)?;
                writeln!(w)
            })?
        }
        "dxf" => save_drawing(
            &myriad_measure::files::profile_drawing(p, corridor)?,
            &a.output,
            a.force,
        )?,
        _ => {
            if p.is_empty() {
                bail!(
                    "the corridor holds no point: no picture to draw (is the line in the dataset's coordinates? `myriad info` gives its bounds)"
                );
            }
            // Labelled: distances along, elevations, the unit, the vertical exaggeration.
            let (w, h, rgba, exaggeration) =
                myriad_render::legend::labelled_profile(p, a.pixels, units_of(ds));
            myriad_io::atomic::AtomicFile::create(&a.output, a.force).and_then(|f| {
                myriad_io::image::write_png(f.temp_path(), w, h, &rgba)?;
                f.commit()
            })?;
            println!(
                "{}: {w} x {h} pixels, vertical exaggeration {exaggeration:.2}",
                a.output.display()
            );
        }
    }
    Ok(())
}

/// The units the dataset's CRS gives its coordinates ("units" where it says none).
fn units_of(ds: &Dataset) -> &'static str {
    myriad_measure::measurement::crs_units(ds.meta.crs.as_deref())
}

#[derive(Args)]
pub struct VolumeArgs {
    /// The dataset (.myr, or its URL)
    dataset: PathBuf,
    /// The polygon in plan: X1,Y1,X2,Y2,X3,Y3[,...] in the dataset's coordinates, or @FILE: a
    /// Polygon in GeoJSON or WKT, or a CSV of x,y vertices (checked against the dataset's CRS)
    #[arg(long, allow_hyphen_values = true)]
    polygon: String,
    /// The base: rim (a plane fitted to the points on the polygon's edge), an elevation, ground
    /// (the dataset's ground points, classes 2 and 11: `myriad ground` first where it has none),
    /// or an earlier dataset of the same ground (.myr)
    #[arg(long, default_value = "rim", allow_hyphen_values = true)]
    base: String,
    /// The grid's cell size [default: about twice the points' spacing]
    #[arg(long)]
    cell: Option<f64>,
    #[command(flatten)]
    filter: FilterArgs,
    /// Print the result as one JSON object
    #[arg(long)]
    json: bool,
    /// Also write the polygon with its volumes as GeoJSON (the CRS named, for QGIS and GDAL)
    #[arg(long, value_name = "FILE")]
    geojson: Option<PathBuf>,
    /// Replace an existing --geojson file
    #[arg(long)]
    force: bool,
}

pub fn volume(a: VolumeArgs) -> Result<()> {
    let shape = xy_arg(&a.polygon, "--polygon", Want::Polygon).map_err(|e| anyhow!(e))?;
    let polygon = Polygon::new(&shape.points).map_err(|e| anyhow!(e))?;
    if let Some(g) = &a.geojson {
        myriad_io::atomic::refuse_input_as_output(g, &[&a.dataset])?;
        if g.exists() && !a.force {
            bail!("{}: output exists (use --force to replace it)", g.display());
        }
    }
    let ds = Dataset::open(&a.dataset)?;
    check_shape(
        &shape,
        &a.polygon,
        "--polygon",
        ds.meta.crs.as_deref(),
        &ds.meta.bounds,
    )
    .map_err(|e| anyhow!(e))?;
    let earlier;
    let base = match a.base.as_str() {
        "rim" => Base::Rim,
        "ground" => Base::Ground,
        b => match b.parse::<f64>() {
            Ok(z) if z.is_finite() => Base::Elevation(z),
            _ if myriad_format::is_dataset(Path::new(b)) || b.starts_with("http") => {
                earlier = Dataset::open(Path::new(b))?;
                Base::Surface(&earlier)
            }
            _ => bail!("--base \"{b}\": expected rim, ground, an elevation or a dataset (.myr)"),
        },
    };
    let bound = a
        .filter
        .filter()?
        .bind(&ds.meta.schema)
        .map_err(|e| anyhow!(e))?;
    let start = Instant::now();
    let v = volume::volume(&ds, &polygon, base, a.cell, &bound).map_err(|e| anyhow!(e))?;
    let secs = start.elapsed().as_secs_f64();
    // In the dataset's own unit (feet where its CRS says so), as every figure beside it.
    let u = units_of(&ds);
    let base_text = match (&base, v.plane) {
        (Base::Rim, Some(p)) => format!(
            "plane fitted to {} rim points, {:.3} {u} at the first vertex, slopes {:.4} east, {:.4} north",
            thousands(v.rim_points),
            p[0],
            p[1],
            p[2]
        ),
        (Base::Elevation(z), _) => format!("elevation {z}"),
        _ => format!("the surface of {}", a.base),
    };
    if let Some(g) = &a.geojson {
        volume_geojson(&a, g, &ds, &polygon, &v, &base_text)?;
    }
    if a.json {
        println!(
            "{}",
            serde_json::json!({
                "fill": v.fill, "cut": v.cut, "net": v.net(), "area": v.area,
                "cell": v.cell, "cells": v.cells, "empty_cells": v.empty_cells,
                "base_empty_cells": v.base_empty_cells, "points": v.points,
                "rim_points": v.rim_points, "plane": v.plane, "base": base_text,
                "nodes_read": v.nodes_read, "seconds": secs,
            })
        );
        return Ok(());
    }
    print_volume(&a, &ds, &v, &base, &base_text, secs);
    Ok(())
}

/// `volume --geojson`: the polygon with the volume's figures as a GeoJSON feature.
fn volume_geojson(
    a: &VolumeArgs,
    g: &Path,
    ds: &Dataset,
    polygon: &Polygon,
    v: &volume::Volume,
    base_text: &str,
) -> Result<()> {
    use myriad_measure::geojson::{collection, feature, polygon_geometry};
    let f = feature(
        polygon_geometry(polygon.vertices(), None),
        serde_json::json!({
            "dataset": a.dataset.display().to_string(),
            "fill": v.fill, "cut": v.cut, "net": v.net(), "area": v.area, "cell": v.cell,
            "cells": v.cells, "empty_cells": v.empty_cells, "base": base_text,
            "points": v.points, "units": units_of(ds),
        }),
    );
    let doc = collection(vec![f], ds.meta.crs.as_deref());
    write_atomic(g, a.force, |w| {
        serde_json::to_writer_pretty(&mut *w, &doc)?;
        writeln!(w)
    })?;
    Ok(())
}

/// The volume's figures, a line each.
fn print_volume(
    a: &VolumeArgs,
    ds: &Dataset,
    v: &volume::Volume,
    base: &Base,
    base_text: &str,
    secs: f64,
) {
    let u = units_of(ds);
    println!("{}", a.dataset.display());
    println!("  fill        {:.3} {u}3 above the base", v.fill);
    println!("  cut         {:.3} {u}3 below the base", v.cut);
    println!("  net         {:.3} {u}3", v.net());
    println!(
        "  area        {:.3} {u}2 ({} cells of {} {u})",
        v.area,
        thousands(v.cells),
        v.cell
    );
    println!("  base        {base_text}");
    let empty = |n: u64| {
        format!(
            "{} ({:.1} %), filled from their neighbours",
            thousands(n),
            100.0 * n as f64 / v.cells.max(1) as f64
        )
    };
    println!("  empty cells {}", empty(v.empty_cells));
    if matches!(base, Base::Surface(_)) {
        println!("  empty cells {} of the base", empty(v.base_empty_cells));
    }
    println!(
        "  points      {} from {} nodes, {secs:.2} s",
        thousands(v.points),
        thousands(v.nodes_read)
    );
}

/// A class scheme file, read; an error names it and the line or member.
pub fn read_scheme(f: &Path) -> Result<myriad_core::classes::Scheme> {
    let text = read_text(f, myriad_measure::scheme::MAX_BYTES, "a class scheme")?;
    myriad_measure::scheme::parse(&text).map_err(|e| anyhow!("{}: {e}", f.display()))
}

/// The text of the file `f` the user gave (`what` it should be), refused past `max` bytes;
/// errors name the file.
pub fn read_text(f: &Path, max: usize, what: &str) -> Result<String> {
    let size = std::fs::metadata(f).map_err(|e| anyhow!("{}: {e}", f.display()))?;
    if size.len() > max as u64 {
        bail!("{}: larger than {max} bytes: not {what}", f.display());
    }
    std::fs::read_to_string(f).map_err(|e| anyhow!("{}: {e}", f.display()))
}

/// The class scheme kept with the saved work of `opened` (a dataset, a scan, tiles), else the
/// default; saved work that cannot be read is said and left alone.
pub fn saved_scheme(opened: &Path) -> myriad_core::classes::Scheme {
    if myriad_format::remote::is_url(opened) {
        return Default::default();
    }
    let sidecar = myriad_measure::work::sidecar_for(opened);
    match myriad_measure::files::load_work(&sidecar, None) {
        Ok(w) => w.classes.unwrap_or_default(),
        Err(e) => {
            eprintln!("warning: {e}: the default class scheme is used");
            Default::default()
        }
    }
}
