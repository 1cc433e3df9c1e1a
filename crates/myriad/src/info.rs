//! `myriad info FILE...`

use anyhow::Result;
use clap::Args;
use myriad_core::units::thousands;
use myriad_format::Dataset;
use myriad_io::{OpenOptions, SourceInfo};
use serde_json::json;
use std::path::PathBuf;

#[derive(Args)]
pub struct InfoArgs {
    /// Point cloud files (LAS, LAZ, COPC, E57, PLY, PCD, PTS, XYZ/CSV/TXT) or datasets (.myr)
    #[arg(required = true)]
    files: Vec<PathBuf>,
    /// One JSON object per file, one per line
    #[arg(long)]
    json: bool,
    /// Report only what the header states, without reading the points (fast, but headers can
    /// be wrong: by default every point is read to count it and measure the real bounds)
    #[arg(long)]
    header_only: bool,
    /// Column layout of text files, e.g. x,y,z,intensity,r,g,b
    #[arg(long)]
    columns: Option<String>,
    /// Placement (trimming box and transform into project coordinates) to apply to every file;
    /// by default a file's sidecar SCAN.placement is applied when it exists (see README)
    #[arg(long, conflicts_with = "no_placement")]
    placement: Option<PathBuf>,
    /// Ignore sidecar placement files
    #[arg(long)]
    no_placement: bool,
}

struct Report {
    info: SourceInfo,
    points: Option<u64>,
    bounds: Option<myriad_core::Aabb>,
    skipped: u64,
    placement: Option<PathBuf>,
    trimmed: u64,
}

pub fn run(args: InfoArgs) -> Result<()> {
    let options = OpenOptions {
        columns: args.columns.clone(),
        placement: args.placement.clone(),
        sidecar_placements: !args.no_placement,
        ..Default::default()
    };
    for path in &args.files {
        // A COPC file on disk is reported as the LAZ file it is (header, point format); over
        // HTTP, and EPT and Potree 2.0 datasets, as the datasets they are read as.
        let las_file = !myriad_format::remote::is_url(path)
            && matches!(
                myriad_io::detect(path),
                Ok(myriad_io::Format::Las | myriad_io::Format::Laz)
            );
        if (myriad_format::is_dataset(path) && !las_file)
            || path
                .extension()
                .is_some_and(|e| e.eq_ignore_ascii_case("myr"))
        {
            dataset_info(path, args.json)?;
            continue;
        }
        let mut src = myriad_io::open(path, &options)?;
        let info = src.info().clone();
        let (points, bounds, skipped) = if args.header_only {
            (info.points, info.bounds, 0)
        } else {
            let (n, b) = myriad_io::scan(src.as_mut())?;
            (Some(n), (n > 0).then_some(b), src.skipped_non_finite())
        };
        if skipped > 0 {
            eprintln!(
                "warning: {}: skipped {skipped} points with NaN or infinite coordinates",
                path.display()
            );
        }
        let r = Report {
            info,
            points,
            bounds,
            skipped,
            placement: src.placement_path().map(|p| p.to_path_buf()),
            trimmed: src.trimmed(),
        };
        // The images an E57 file carries.
        let images = match r.info.format {
            // (Images that do not read are said, the points' report kept.)
            myriad_io::Format::E57 => myriad_io::e57_images::images(path).unwrap_or_else(|e| {
                eprintln!("warning: {e}: its images not listed");
                Vec::new()
            }),
            _ => Vec::new(),
        };
        if args.json {
            let mut v = to_json(&r);
            if !images.is_empty() {
                v["images"] = images
                    .iter()
                    .map(|im| {
                        json!({
                            "name": im.name, "model": im.model_name(), "width": im.width,
                            "height": im.height, "format": im.format, "bytes": im.bytes(),
                            "pose": im.pose.map(|(q, t)| json!({"rotation": q, "translation": t})),
                        })
                    })
                    .collect();
            }
            println!("{v}");
        } else {
            print_human(&r);
            for (i, im) in images.iter().enumerate() {
                let place = match im.pose {
                    Some((_, t)) => format!("at {:.3}, {:.3}, {:.3}", t[0], t[1], t[2]),
                    None => "no pose (shown with the data, not placed)".into(),
                };
                println!(
                    "  image {}     \"{}\": {} {}x{} {} ({} bytes), {place}",
                    i + 1,
                    im.name,
                    im.model_name(),
                    im.width,
                    im.height,
                    im.format.to_uppercase(),
                    thousands(im.bytes())
                );
            }
        }
    }
    Ok(())
}

fn to_json(r: &Report) -> serde_json::Value {
    let i = &r.info;
    json!({
        "path": i.path.display().to_string(),
        "format": i.format.name(),
        "version": i.version,
        "points": r.points,
        "header_points": i.points,
        "skipped_non_finite": r.skipped,
        "placement": r.placement.as_ref().map(|p| p.display().to_string()),
        "trimmed": r.trimmed,
        "bounds": r.bounds.map(|b| json!({"min": b.min, "max": b.max})),
        "header_bounds": i.bounds.map(|b| json!({"min": b.min, "max": b.max})),
        "attributes": i.schema.names(),
        "crs": i.crs,
        "crs_info": crs_json(i.crs.as_deref()),
        "scale": i.scale,
        "offset": i.offset,
        "file_size": i.file_size,
    })
}

fn print_human(r: &Report) {
    let i = &r.info;
    println!("{}", i.path.display());
    println!("  format      {} {}", i.format.name(), i.version);
    match r.points {
        Some(n) => println!("  points      {}", thousands(n)),
        None => println!("  points      unknown (header has no count)"),
    }
    if r.skipped > 0 {
        println!(
            "  skipped     {} with NaN/infinite coordinates",
            thousands(r.skipped)
        );
    }
    if let Some(b) = r.bounds {
        print_bounds(&b);
    }
    println!("  attributes  {}", i.schema);
    if let (Some(s), Some(o)) = (i.scale, i.offset) {
        println!("  scale       {} {} {}", s[0], s[1], s[2]);
        println!("  offset      {} {} {}", o[0], o[1], o[2]);
    }
    print_crs(i.crs.as_deref());
    println!("  file size   {} bytes", thousands(i.file_size));
}

/// The bounds lines of the human summary (files and datasets).
pub fn print_bounds(b: &myriad_core::Aabb) {
    let s = b.size();
    println!(
        "  bounds min  {:.3} {:.3} {:.3}",
        b.min[0], b.min[1], b.min[2]
    );
    println!(
        "         max  {:.3} {:.3} {:.3}",
        b.max[0], b.max[1], b.max[2]
    );
    println!("         size {:.3} x {:.3} x {:.3}", s[0], s[1], s[2]);
}

/// What the CRS says of itself (`myriad_measure::crs::describe`): name, EPSG code, kind,
/// units, vertical part.
fn crs_json(crs: Option<&str>) -> serde_json::Value {
    let Some(d) = crs.map(myriad_measure::crs::describe) else {
        return serde_json::Value::Null;
    };
    json!({
        "name": d.name, "epsg": d.epsg, "kind": d.kind, "units": d.units,
        "vertical": d.vertical.map(|(n, c, u)| json!({ "name": n, "epsg": c, "units": u })),
    })
}

/// The CRS lines of the human summary: what it names (name, EPSG code, kind, units, vertical
/// part), then the text, long WKT cut at 100 characters.
pub fn print_crs(crs: Option<&str>) {
    if let Some(c) = crs {
        println!("  crs name    {}", myriad_measure::crs::describe(c).line());
    }
    match crs {
        Some(c) if c.len() > 100 => println!(
            "  crs         {}...",
            &c[..c.char_indices().nth(100).map_or(c.len(), |x| x.0)]
        ),
        Some(c) => println!("  crs         {c}"),
        None => println!("  crs         none"),
    }
}

/// `info` on a dataset: its metadata and the table of its levels.
fn dataset_info(path: &std::path::Path, as_json: bool) -> Result<()> {
    // What is stored: a damaged edits file beside it does not hide the dataset.
    let ds = Dataset::open_stored(path)?;
    let m = &ds.meta;
    // Per level: nodes, points, and the finest spacing; from the metadata (one read however
    // large the dataset), or by walking every hierarchy page where a dataset written before
    // the table was kept there lacks it.
    let (levels, damage) = if m.levels.is_empty() {
        let (nodes, damage) = ds.nodes();
        for d in &damage {
            eprintln!("warning: {}", ds.damage_error(d));
        }
        (myriad_format::Level::table(&nodes), Some(damage.len()))
    } else {
        (m.levels.clone(), None)
    };
    // A dataset of several files counts the bytes of the files it links (the parts' files
    // hold their headers and hierarchies too).
    let linked: u64 = ds.files().iter().map(|f| f.length).sum();
    let bpp = (ds.file_length + linked) as f64 / m.points.max(1) as f64;
    let version = match ds.files().is_empty() {
        true => myriad_format::FORMAT_VERSION,
        false => myriad_format::LINKED_VERSION,
    };
    // A dataset read in place (COPC, EPT, Potree 2.0) counts its nodes by walking its pages.
    let foreign = ds.foreign_format();
    let (nodes, depth) = match foreign {
        Some(_) => (
            levels.iter().map(|l| l.nodes).sum(),
            levels.last().map_or(0, |l| l.level),
        ),
        None => (m.nodes, m.depth),
    };
    if as_json {
        println!(
            "{}",
            json!({
                "path": path.display().to_string(),
                "format": foreign.unwrap_or("myriad"),
                "version": version,
                "read_in_place": foreign.is_some(),
                "points": m.points,
                "nodes": nodes,
                "depth": depth,
                "structure": m.structure,
                "parameters": m.parameters,
                "bounds": json!({"min": m.bounds.min, "max": m.bounds.max}),
                "root": json!({"min": m.root.min, "max": m.root.max}),
                "scale": m.quantization.scale,
                "offset": m.quantization.offset,
                "crs": m.crs,
                "crs_info": crs_json(m.crs.as_deref()),
                "attributes": m.schema.names(),
                "file_size": ds.file_length,
                "files": ds.files().iter().map(|f| json!({"path": f.path, "bytes": f.length})).collect::<Vec<_>>(),
                "bytes_per_point": bpp,
                "sources": m.sources,
                "levels": levels.iter().map(|l| json!({"level": l.level, "nodes": l.nodes, "points": l.points, "node_size": l.spacing.is_finite().then_some(l.spacing)})).collect::<Vec<_>>(),
                "damaged_hierarchy_pages": damage,
            })
        );
        return Ok(());
    }
    let b = m.bounds;
    println!("{}", path.display());
    match foreign {
        Some(f) => println!("  format      {f}, read in place"),
        None => println!("  format      Myriad dataset {version}"),
    }
    println!("  structure   {} {}", m.structure, m.parameters);
    println!("  points      {}", thousands(m.points));
    println!("  nodes       {} (depth {depth})", thousands(nodes));
    print_bounds(&b);
    println!("  attributes  {}", m.schema);
    let q = m.quantization;
    println!("  scale       {} {} {}", q.scale[0], q.scale[1], q.scale[2]);
    print_crs(m.crs.as_deref());
    if foreign.is_none() || ds.file_length > 0 {
        println!(
            "  file size   {} bytes, {:.2} bytes per point",
            thousands(ds.file_length + linked),
            bpp
        );
    }
    if !ds.files().is_empty() {
        println!(
            "  files       its own ({} bytes) and {} it links, beside it: {}{}",
            thousands(ds.file_length),
            ds.files().len(),
            ds.files()[0].path,
            if ds.files().len() > 1 { ", ..." } else { "" }
        );
    }
    println!("  level      nodes         points   node size");
    for l in &levels {
        println!(
            "  {:>5} {:>10} {:>14} {:>11.3}",
            l.level,
            thousands(l.nodes),
            thousands(l.points),
            l.spacing
        );
    }
    Ok(())
}
