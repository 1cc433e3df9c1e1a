//! `myriad mesh DATASET -o OUT.ply|OUT.glb`: the surface reconstructed from what a view draws
//! (seed 001), as a mesh file; and the surface options `render` and `view` share.

use anyhow::{Result, bail};
use clap::Args;
use myriad_format::Dataset;
use myriad_lod::SelectOptions;
use myriad_render::Scene;
use myriad_render::surface::{self, Built, Density, Kind, Normals, Surface};
use std::path::PathBuf;
use std::sync::Arc;

fn parse_neighbours(s: &str) -> Result<u32, String> {
    match s {
        "0" => Ok(0),
        "1" => Ok(1),
        "3" => Ok(3),
        _ => Err(format!("\"{s}\": 0, 1 or 3")),
    }
}

/// The options of a surface (seed 001), as `render`, `view` and `mesh` take them.
#[derive(Args, Clone, Debug)]
pub struct SurfaceArgs {
    /// Columns, rows and depth layers of the view-frustum grid
    #[arg(long, value_parser = surface::parse_grid, default_value = "150x150x50")]
    pub grid: [u32; 3],
    /// Cell normals: tensor (the point distribution tensor's minor eigenvector) or cells (towards
    /// the empty neighbour cells, faster, rougher)
    #[arg(long, value_parser = Normals::parse, default_value = "tensor")]
    pub normals: Normals,
    /// Neighbours a point may move to, per point: 0 (no move), 1 (along its largest offset) or
    /// 3 (along each axis)
    #[arg(long, value_parser = parse_neighbours, default_value = "3")]
    pub neighbours: u32,
    /// Cluster only: the same as --neighbours 0
    #[arg(long)]
    pub no_move: bool,
    /// The density that moves points: count (points per cell) or planarity (of the cell's
    /// point distribution tensor)
    #[arg(long, value_parser = Density::parse, default_value = "count")]
    pub density: Density,
    /// The exponent of the move's weights (seed 001 equation 8)
    #[arg(long, default_value_t = 2.0)]
    pub gamma: f64,
    /// The lower bound of the move's weights, 0 to 0.5
    #[arg(long, default_value_t = 0.1)]
    pub lb: f64,
}

impl SurfaceArgs {
    /// The surface of this kind with these options.
    pub fn surface(&self, kind: Kind) -> Result<Surface> {
        if !(self.gamma > 0.0 && self.gamma <= 16.0) {
            bail!("--gamma must be above 0 and at most 16");
        }
        if !(0.0..0.5).contains(&self.lb) {
            bail!("--lb must be from 0 to below 0.5");
        }
        Ok(Surface {
            kind,
            grid: self.grid,
            normals: self.normals,
            neighbours: if self.no_move { 0 } else { self.neighbours },
            density: self.density,
            gamma: self.gamma,
            lb: self.lb,
        })
    }
}

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
    /// Eye and target: EX,EY,EZ,TX,TY,TZ [default: the whole dataset from above at 45 degrees]
    #[arg(long, value_parser = crate::render::parse_floats::<6>, allow_hyphen_values = true)]
    pub camera: Option<[f64; 6]>,
    /// One of the standard views instead of --camera: overview, top, close
    #[arg(long, conflicts_with = "camera", value_parser = ["overview", "top", "close"])]
    pub view: Option<String>,
    /// Up direction
    #[arg(long, value_parser = crate::render::parse_floats::<3>, default_value = "0,0,1", allow_hyphen_values = true)]
    pub up: [f64; 3],
    /// Vertical field of view in degrees
    #[arg(long, default_value_t = 60.0)]
    pub fov: f64,
    /// The view's image size (the grid spans it)
    #[arg(long, default_value_t = 1280)]
    pub width: u32,
    #[arg(long, default_value_t = 720)]
    pub height: u32,
    /// Most points drawn, and so clustered
    #[arg(long, value_parser = crate::synth::parse_count, default_value = "5M")]
    pub budget: u64,
    /// Colour of the cells: rgb, intensity, elevation, classification, return, source, level,
    /// uniform
    #[arg(long, value_parser = crate::render::parse_color, default_value = "rgb")]
    pub color: myriad_render::ColorBy,
    #[command(flatten)]
    pub options: SurfaceArgs,
    /// Replace an existing output
    #[arg(long)]
    pub force: bool,
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
    let mut scene = Scene::open(ds.clone(), 2 << 30, 1 << 30);
    if scene.hierarchy.pages() == 0
        && let Err(d) = ds.hierarchy_page(&ds.root_page())
    {
        bail!("{} (nothing left to draw)", ds.damage_error(&d));
    }
    scene.set_colour(colour);
    let (w, h, fov) = size;
    let mut cam = match view {
        Some(v) => crate::render::view_camera(Some(v), &scene.view_bounds, &ds.meta.bounds, w, h)?,
        None => crate::render::camera(
            &scene.view_bounds,
            &ds.meta.bounds,
            eye_target,
            up,
            w,
            h,
            fov,
        )?,
    };
    cam.fov_y = fov;
    // u64::MAX: every point (no level of detail).
    let options = SelectOptions {
        budget,
        min_pixels: if budget == u64::MAX { 0.0 } else { 1.0 },
    };
    scene.last = scene.converge(&cam, &options, None);
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
    let s = a.options.surface(a.surface)?;
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
        crate::info::thousands(c.cells.len() as u64),
        crate::info::thousands(c.inside as u64),
        crate::info::thousands(c.moved as u64),
        crate::info::thousands(built.mesh.positions.len() as u64),
        crate::info::thousands(built.mesh.triangles.len() as u64),
        c.cluster.as_secs_f64() * 1e3,
        c.moving.as_secs_f64() * 1e3,
        c.reduce.as_secs_f64() * 1e3,
        built.reconstruct.as_secs_f64() * 1e3,
    );
    Ok(())
}
