//! `myriad mesh DATASET -o OUT.ply|OUT.glb`: the surface reconstructed from what a view draws
//! (Schiffner et al. 2015), as a mesh file; and the surface options `render` and `view` share.

use anyhow::{Result, bail};
use clap::Args;
use myriad_format::Dataset;
use myriad_render::Scene;
use myriad_render::surface::{self, Built, Kind};
use std::path::PathBuf;
use std::sync::Arc;

#[derive(Args)]
pub struct MeshArgs {
    /// The dataset (.myr)
    pub dataset: PathBuf,
    /// The mesh to write: .ply (binary, double-precision positions) or .glb (binary glTF)
    #[arg(short, long)]
    pub output: PathBuf,
    /// Surface element per cell: quads (cell-filling), boxes or splats (octagons)
    #[arg(long, value_parser = Kind::parse, default_value = "quads")]
    pub surface: Kind,
    /// Replace an existing output
    #[arg(long)]
    pub force: bool,
    /// Eye and target: EX,EY,EZ,TX,TY,TZ [default: the whole dataset from above at 45 degrees]
    #[arg(help_heading = "Camera", long, value_parser = myriad_core::units::parse_floats::<6>, allow_hyphen_values = true)]
    pub camera: Option<[f64; 6]>,
    /// One of the standard views instead of --camera: overview, top, close
    #[arg(help_heading = "Camera", long, conflicts_with = "camera", value_parser = ["overview", "top", "close"])]
    pub view: Option<String>,
    /// Up direction
    #[arg(help_heading = "Camera", long, value_parser = myriad_core::units::parse_floats::<3>, default_value = "0,0,1", allow_hyphen_values = true)]
    pub up: [f64; 3],
    /// Vertical field of view in degrees
    #[arg(help_heading = "Camera", long, default_value_t = 60.0)]
    pub fov: f64,
    /// The view's image size (the grid spans it)
    #[arg(help_heading = "Camera", long, default_value_t = 1280)]
    pub width: u32,
    #[arg(help_heading = "Camera", long, default_value_t = 720)]
    pub height: u32,
    /// Most points drawn, and so clustered
    #[arg(long, value_parser = myriad_core::units::parse_count, default_value = "5M")]
    pub budget: u64,
    /// Colour of the cells: rgb, intensity, elevation, classification, return, source, level,
    /// uniform
    #[arg(long, value_parser = myriad_render::args::parse_color, default_value = "rgb")]
    pub color: myriad_render::ColorBy,
    #[command(flatten, next_help_heading = "Surface")]
    pub options: myriad_render::args::SurfaceArgs,
}

/// A scene of a dataset whose last selection is everything a view selects at `budget`, loaded,
/// and the view's camera: what a surface is made from ([`surface::drawn_points`]).
pub fn drawn(
    dataset: &std::path::Path,
    eye_target: Option<[f64; 6]>,
    view: Option<&str>,
    up: [f64; 3],
    size: (u32, u32, f64),
    budget: u64,
    colour: myriad_render::ColorBy,
) -> Result<(Scene, myriad_lod::Camera)> {
    let ds = Arc::new(Dataset::open(&crate::cached::dataset_for(dataset)?)?);
    let all = ds.meta.bounds;
    let (w, h, fov) = size;
    let (scene, cam) = surface::drawn_scene(ds, budget, colour, |bounds| {
        let mut cam = match view {
            Some(v) => myriad_lod::Camera::view(Some(v), bounds, &all, w, h)
                .ok_or_else(|| format!("no standard view \"{v}\""))?,
            None => crate::render::camera(bounds, &all, eye_target, up, w, h, fov)
                .map_err(|e| e.to_string())?,
        };
        cam.fov_y = fov;
        Ok(cam)
    })
    .map_err(anyhow::Error::msg)?;
    for why in scene.loader.failed_pages().values() {
        eprintln!("warning: {why}");
    }
    Ok((scene, cam))
}

pub fn run(a: MeshArgs) -> Result<()> {
    myriad_io::atomic::refuse_input_as_output(&a.output, &[&a.dataset])?;
    if a.output.exists() && !a.force {
        bail!(
            "{}: output exists (use --force to replace it)",
            a.output.display()
        );
    }
    let ext = a
        .output
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    if !matches!(ext.as_deref(), Some("ply" | "glb")) {
        bail!("{}: a mesh is written as .ply or .glb", a.output.display());
    }
    if a.width == 0 || a.height == 0 || a.width > 16384 || a.height > 16384 {
        bail!("--width and --height must be 1 to 16384");
    }
    if !(a.fov > 0.0 && a.fov < 180.0) {
        bail!("--fov must be between 0 and 180 degrees");
    }
    let s = a.options.surface(a.surface).map_err(anyhow::Error::msg)?;
    let (scene, cam) = drawn(
        &a.dataset,
        a.camera,
        a.view.as_deref(),
        a.up,
        (a.width, a.height, a.fov),
        a.budget,
        a.color,
    )?;
    let (points, colours) = surface::drawn_points(&scene, None);
    let built = Built::new(&cam, &points, &colours, &s);
    if built.mesh.triangles.is_empty() {
        bail!("{}: no point in view, no surface", a.dataset.display());
    }
    myriad_io::mesh::write(&a.output, &built.mesh, true)?;
    let c = &built.clustering;
    println!(
        "{}: {} cells from {} points in view ({} moved), {} vertices, {} triangles; cluster {:.1} ms, move {:.1} ms, reduce {:.1} ms, reconstruct {:.1} ms",
        a.output.display(),
        myriad_core::units::thousands(c.cells.len() as u64),
        myriad_core::units::thousands(c.inside as u64),
        myriad_core::units::thousands(c.moved as u64),
        myriad_core::units::thousands(built.mesh.positions.len() as u64),
        myriad_core::units::thousands(built.mesh.triangles.len() as u64),
        c.cluster.as_secs_f64() * 1e3,
        c.moving.as_secs_f64() * 1e3,
        c.reduce.as_secs_f64() * 1e3,
        built.reconstruct.as_secs_f64() * 1e3,
    );
    Ok(())
}
