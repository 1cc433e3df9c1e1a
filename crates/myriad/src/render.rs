//! `myriad render DATASET -o OUT.png`: a headless image through the LOD selection and the
//! compute rasterizer.

use anyhow::{Result, bail};
use clap::Args;
use myriad_build::open::{Opened, Opener, Preview};
use myriad_core::Aabb;
use myriad_core::units::parse_floats;
use myriad_format::Dataset;
use myriad_io::image::write_png;
use myriad_lod::{Camera, Occlusion, SelectOptions};
use myriad_render::args::{
    parse_lod_threshold, parse_passes, parse_path, parse_point_size, parse_shape,
};
use myriad_render::{Edl, Gpu, Passes, Path, PointSize, Rasterizer, Scene, Shape, Style};
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

#[derive(Args)]
pub struct RenderArgs {
    /// The dataset (.myr), or a scan or a folder of LAS/LAZ tiles (converted once into a
    /// dataset kept next to it)
    dataset: PathBuf,
    /// The image to write (.png)
    #[arg(short, long)]
    output: PathBuf,
    #[arg(long, default_value_t = 1280)]
    width: u32,
    #[arg(long, default_value_t = 720)]
    height: u32,
    /// Eye-dome lighting: adds edl to --passes
    #[arg(long)]
    edl: bool,
    /// Draw the first image there is without waiting: a LAS/LAZ scan whose dataset is not
    /// built yet is drawn from a preview read without decoding it (the first point of each LAZ
    /// chunk, LAS records at a stride), and not converted; a dataset as without it
    #[arg(long, conflicts_with_all = ["stereo", "surface"])]
    no_wait: bool,
    /// Replace an existing output
    #[arg(long)]
    force: bool,
    /// Eye and target: EX,EY,EZ,TX,TY,TZ [default: the whole dataset from above at 45 degrees]
    #[arg(help_heading = "Camera", long, value_parser = parse_floats::<6>, allow_hyphen_values = true)]
    camera: Option<[f64; 6]>,
    /// One of the standard views instead of --camera: overview (the default), top, close
    #[arg(help_heading = "Camera", long, conflicts_with = "camera", value_parser = ["overview", "top", "close"])]
    view: Option<String>,
    /// Up direction
    #[arg(help_heading = "Camera", long, value_parser = parse_floats::<3>, default_value = "0,0,1", allow_hyphen_values = true)]
    up: [f64; 3],
    /// Vertical field of view in degrees
    #[arg(help_heading = "Camera", long, default_value_t = 60.0)]
    fov: f64,
    /// Most points drawn
    #[arg(long, value_parser = myriad_core::units::parse_count, default_value = "5M")]
    budget: u64,
    /// Draw every point of the dataset (the reference image)
    #[arg(long)]
    full: bool,
    #[command(flatten, next_help_heading = "Colour")]
    colour: crate::measure::ColourArgs,
    /// Point size: fixed:PX, or adaptive (the spacing of the level of detail drawn, as seen)
    #[arg(help_heading = "Points and passes", long, value_parser = parse_point_size, default_value = "adaptive")]
    point_size: PointSize,
    /// Point shape: square, round, paraboloid
    #[arg(help_heading = "Points and passes", long, value_parser = parse_shape, default_value = "square")]
    shape: Shape,
    /// Post passes over the frame, comma-separated, run in the pipeline's order whatever the
    /// order given: fill (hole filling), shade (headlight on normals), ssao (ambient
    /// occlusion), edl (eye-dome lighting), blur, aa (2x2 supersampling); or none
    #[arg(help_heading = "Points and passes", long, value_parser = parse_passes, default_value = myriad_render::DEFAULT_PASSES)]
    passes: Passes,
    /// Eye-dome lighting strength
    #[arg(help_heading = "Points and passes", long, default_value_t = 1.0)]
    edl_strength: f32,
    /// Eye-dome lighting radius in pixels
    #[arg(help_heading = "Points and passes", long, default_value_t = 1.4)]
    edl_radius: f32,
    /// Draw only the points in this box: MINX,MINY,MINZ,MAXX,MAXY,MAXZ
    #[arg(help_heading = "Clipping and filters", long, value_parser = parse_floats::<6>, allow_hyphen_values = true)]
    clip: Option<[f64; 6]>,
    /// With --clip: draw only the points outside the box
    #[arg(help_heading = "Clipping and filters", long, requires = "clip")]
    clip_outside: bool,
    /// Rasterizer: compute (needs 64-bit atomics), quads, or cpu [default: compute on a
    /// hardware GPU, quads on one without 64-bit atomics; cpu without one]
    #[arg(help_heading = "Points and passes", long = "raster", value_parser = parse_path)]
    path: Option<Path>,
    /// Cull nodes hidden behind nearer ones: checked (the software test, each node it culls
    /// then queried against the frame: one that shows is drawn, frames repeated until the
    /// selection settles), software (a coarse depth buffer filled by the nodes already
    /// selected), queries (the nodes' boxes tested against each frame's depth, hardware
    /// occlusion queries on a GPU: they act from the next frame) or off
    #[arg(help_heading = "Level of detail and culling", long, value_parser = Occlusion::parse, default_value = "checked")]
    occlusion: Occlusion,
    /// mwkd datasets whose normals have a sign (the input's, or turned towards their scanners
    /// or flight lines): leave out nodes whose normal cones all face away (on), or draw them
    /// (off)
    #[arg(help_heading = "Level of detail and culling", long, value_parser = ["on", "off"], default_value = "on")]
    normal_cones: String,
    /// Cells per side of the occlusion depth buffer
    #[arg(help_heading = "Level of detail and culling", long, default_value_t = myriad_lod::occlusion::DEFAULT_SIZE,
          value_parser = clap::value_parser!(u32).range(8..=1024))]
    occlusion_size: u32,
    /// Pixels a level's point spacing must cover to be drawn (1 or 2 are usual)
    #[arg(help_heading = "Level of detail and culling", long, value_parser = parse_lod_threshold, default_value = "1")]
    lod_threshold: f64,
    /// Stereo: the left and right eyes side by side, each --width x --height, from
    /// one selection for both eyes (single-pass on the CPU path)
    #[arg(help_heading = "Stereo", long, conflicts_with = "surface")]
    stereo: bool,
    /// With --stereo: the distance between the eyes, in the dataset's units
    #[arg(
        help_heading = "Stereo",
        long,
        default_value_t = 0.064,
        requires = "stereo"
    )]
    ipd: f64,
    /// With --stereo: one frame per eye instead of one pass over the points for both
    #[arg(help_heading = "Stereo", long, requires = "stereo")]
    two_pass: bool,
    /// With --stereo: black out the pixels a headset's lens cannot show (outside the ellipse
    /// inscribed in each eye's image)
    #[arg(help_heading = "Stereo", long, requires = "stereo")]
    hidden_area: bool,
    /// Draw the surface the points make instead of the points: quads (cell-filling),
    /// boxes or splats, one per cell of a grid in the view frustum, lit by a headlight
    #[arg(help_heading = "Surface", long, value_parser = myriad_render::surface::Kind::parse)]
    surface: Option<myriad_render::surface::Kind>,
    #[command(flatten, next_help_heading = "Surface")]
    surface_options: myriad_render::args::SurfaceArgs,
    #[command(flatten, next_help_heading = "Clipping and filters")]
    filter: crate::measure::FilterArgs,
}

pub fn run(a: RenderArgs) -> Result<()> {
    check(&a)?;
    let filter = a.filter.filter()?;
    let surface = (a.surface.map(|k| a.surface_options.surface(k)).transpose())
        .map_err(anyhow::Error::msg)?;
    let t0 = Instant::now();
    let (gpu, raster) = drawing_on(a.path)?;
    let style = style_of(&a);
    let preview = if a.no_wait {
        Preview::Sample
    } else {
        Preview::None
    };
    let dataset = match crate::cached::open(&mut Opener::new(preview), &a.dataset)? {
        Opened::Dataset(d) => d,
        Opened::Preview(p) => {
            return render_preview(&a, &p.files, &filter, &gpu, &raster, &style, t0);
        }
    };
    let ds = Arc::new(Dataset::open(&dataset)?);
    let options = SelectOptions {
        budget: if a.full { u64::MAX } else { a.budget },
        min_pixels: if a.full { 0.0 } else { a.lod_threshold },
    };
    let mut scene = scene_of(&a, &ds, &filter)?;
    let cam = view_of(&a, &scene.view_bounds, &ds.meta.bounds)?;
    if a.stereo {
        return render_stereo(&a, &mut scene, &ds, (&gpu, &raster), &cam, &options, &style);
    }
    let still = myriad_render::still::draw(
        &mut scene,
        &gpu,
        &raster,
        &cam,
        &options,
        &style,
        surface.as_ref(),
        t0,
    );
    if let Some(s) = &still.surface {
        print_surface(s);
    }
    // An image of two versions of a dataset replaced on its server is no image of either.
    ds.check_unchanged()?;
    write_png(&a.output, a.width, a.height, &still.image)?;
    let damaged = warn_damage(&scene);
    if let Some((requests, bytes)) = ds.fetched() {
        println!(
            "fetched {} bytes in {requests} range requests ({:.2} % of the dataset's {} bytes)",
            myriad_core::units::thousands(bytes),
            100.0 * bytes as f64 / ds.file_length.max(1) as f64,
            myriad_core::units::thousands(ds.file_length)
        );
    }
    let stats = &still.stats;
    println!(
        "{}: {} points in {} nodes ({} hidden nodes culled), {:.1} bytes a point in the point buffers ({:.1} read per drawn point), frame {:.1} ms, first image after {:.2} s, converged after {:.2} s ({}, {:?} path)",
        a.output.display(),
        myriad_core::units::thousands(stats.points),
        stats.nodes,
        stats.culled,
        stats.gpu_bytes as f64 / stats.gpu_points.max(1) as f64,
        stats.read_bytes as f64 / stats.points.max(1) as f64,
        still.frame.as_secs_f64() * 1e3,
        still.first_image.as_secs_f64(),
        still.converged.as_secs_f64(),
        gpu.name,
        raster.path,
    );
    // Every selected point drawn, but those of damaged pages (and those its edits remove).
    debug_assert!(damaged > 0 || stats.points == still.selected_points || ds.edits().is_some());
    full_image_whole(&a, damaged)
}

/// The options' values checked before anything is read: the output a PNG that is not an
/// input (nor there, without --force), the image's size, the field of view, the clipping box,
/// eye-dome lighting's strength and radius.
fn check(a: &RenderArgs) -> Result<()> {
    if !a
        .output
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("png"))
    {
        bail!("{}: render writes a PNG image (.png)", a.output.display());
    }
    myriad_io::atomic::refuse_input_as_output(&a.output, &[&a.dataset])?;
    if a.output.exists() && !a.force {
        bail!(
            "{}: output exists (use --force to replace it)",
            a.output.display()
        );
    }
    if a.width == 0 || a.height == 0 || a.width > 16384 || a.height > 16384 {
        bail!("--width and --height must be 1 to 16384");
    }
    if !(a.fov > 0.0 && a.fov < 180.0) {
        bail!("--fov must be between 0 and 180 degrees");
    }
    if let Some(c) = a.clip
        && !(c[0] <= c[3] && c[1] <= c[4] && c[2] <= c[5])
    {
        bail!("--clip: each minimum must be at most its maximum");
    }
    if !(a.edl_strength >= 0.0 && a.edl_strength <= 100.0) {
        bail!("--edl-strength must be from 0 to 100");
    }
    if !(a.edl_radius >= 0.5 && a.edl_radius <= 32.0) {
        bail!("--edl-radius must be from 0.5 to 32 pixels");
    }
    Ok(())
}

/// The device and rasterizer `--raster` asks for: the CPU; any adapter (a software one too)
/// for a GPU path; by default the best there is, else the CPU with a warning saying why.
fn drawing_on(path: Option<Path>) -> Result<(Gpu, Rasterizer)> {
    let (gpu, why) = match path {
        Some(Path::Cpu) => (Gpu::cpu(), None),
        Some(_) => (Gpu::headless().map_err(anyhow::Error::msg)?, None),
        None => Gpu::best(),
    };
    if let Some(why) = why {
        eprintln!("warning: {why}: drawing on the CPU");
    }
    let raster = match path {
        Some(Path::Compute) if !gpu.atomics => bail!(
            "{}: no 64-bit atomics, so no compute path (--raster quads or cpu)",
            gpu.name
        ),
        Some(p) => Rasterizer::with_path(&gpu, p),
        None => Rasterizer::new(&gpu),
    };
    Ok((gpu, raster))
}

/// How points are drawn: size, shape, post passes (`--edl` adding eye-dome lighting) and the
/// clipping box.
fn style_of(a: &RenderArgs) -> Style {
    Style {
        size: a.point_size,
        shape: a.shape,
        passes: Passes {
            edl: (a.edl || a.passes.edl.is_some()).then_some(Edl {
                strength: a.edl_strength,
                radius: a.edl_radius,
            }),
            ..a.passes
        },
        background: [0, 0, 0, 255],
        clip: a.clip.map(|c| myriad_render::Clip {
            bounds: Aabb::new([c[0], c[1], c[2]], [c[3], c[4], c[5]]),
            inside: !a.clip_outside,
        }),
    }
}

/// The scene of `ds` as the options ask: its points filtered, coloured, culled. Caches as the
/// viewer's: 2 GiB of decoded points, 1 GiB on the GPU (what a frame uses is kept even beyond
/// them). A damaged root hierarchy page (the only one read before drawing) leaves nothing to
/// draw; damage below is reported as the view reaches it.
fn scene_of(a: &RenderArgs, ds: &Arc<Dataset>, filter: &myriad_measure::Filter) -> Result<Scene> {
    let bound = filter.bind(&ds.meta.schema).map_err(anyhow::Error::msg)?;
    let mut scene = Scene::open_filtered(ds.clone(), bound, 2 << 30, 1 << 30);
    if scene.hierarchy.pages() == 0
        && let Err(d) = ds.hierarchy_page(&ds.root_page())
    {
        bail!("{} (nothing left to draw)", ds.damage_error(&d));
    }
    scene.set_colour(a.colour.for_dataset(ds)?);
    scene.occlusion = a.occlusion;
    scene.occlusion_size = a.occlusion_size;
    if a.normal_cones == "off" {
        std::sync::Arc::make_mut(&mut scene.hierarchy).cull_backfaces = false;
    }
    Ok(scene)
}

/// `render --stereo`: both eyes side by side from one selection.
fn render_stereo(
    a: &RenderArgs,
    scene: &mut Scene,
    ds: &Dataset,
    (gpu, raster): (&Gpu, &Rasterizer),
    cam: &Camera,
    options: &SelectOptions,
    style: &Style,
) -> Result<()> {
    if !(a.ipd >= 0.0 && a.ipd.is_finite()) {
        bail!("--ipd must be a distance of 0 or more");
    }
    let eyes = cam.eyes(a.ipd);
    let stereo = myriad_render::stereo::Stereo {
        ipd: a.ipd,
        single_pass: !a.two_pass,
        hidden_area: a.hidden_area,
    };
    scene.converge_with(&|s: &Scene| s.select_eyes(&eyes, options, style.clip));
    let t = Instant::now();
    let (img, stats) = scene.frame_stereo(gpu, raster, &eyes, options, style, &stereo, None);
    let frame = t.elapsed();
    ds.check_unchanged()?;
    write_png(&a.output, 2 * a.width, a.height, &img)?;
    let damaged = warn_damage(scene);
    println!(
        "{}: both eyes side by side ({}x{} each, {} apart): {} points in {} nodes, frame {:.1} ms ({}, {:?} path, {})",
        a.output.display(),
        a.width,
        a.height,
        a.ipd,
        myriad_core::units::thousands(stats.points),
        stats.nodes,
        frame.as_secs_f64() * 1e3,
        gpu.name,
        raster.path,
        if a.two_pass || raster.path != Path::Cpu {
            "two passes"
        } else {
            "single pass"
        },
    );
    full_image_whole(a, damaged)
}

/// What making and drawing the surface took.
fn print_surface(s: &myriad_render::still::SurfaceDrawn) {
    if let Some(why) = &s.on_cpu {
        eprintln!("warning: {why}: the surface is made on the CPU");
    }
    let (c, built) = (&s.built.clustering, &s.built);
    println!(
        "surface: {} cells ({} triangles) from {} points in view ({} moved); cluster {:.1} ms, move {:.1} ms, reduce {:.1} ms, reconstruct {:.1} ms, made in {:.1} ms, drawn in {:.1} ms",
        myriad_core::units::thousands(c.cells.len() as u64),
        myriad_core::units::thousands(built.mesh.triangles.len() as u64),
        myriad_core::units::thousands(c.inside as u64),
        myriad_core::units::thousands(c.moved as u64),
        c.cluster.as_secs_f64() * 1e3,
        c.moving.as_secs_f64() * 1e3,
        c.reduce.as_secs_f64() * 1e3,
        built.reconstruct.as_secs_f64() * 1e3,
        s.made.as_secs_f64() * 1e3,
        s.drawn.as_secs_f64() * 1e3,
    );
}

/// `render --no-wait` of a LAS/LAZ scan, or a folder of tiles, without its dataset: its preview
/// (each file's), drawn at once.
fn render_preview(
    a: &RenderArgs,
    files: &[PathBuf],
    filter: &myriad_measure::Filter,
    gpu: &Gpu,
    raster: &Rasterizer,
    style: &Style,
    t0: Instant,
) -> Result<()> {
    let tiles = myriad_io::las_preview::preview_files(
        files,
        PREVIEW_POINTS,
        myriad_io::las_preview::PREVIEW_BUDGET,
    )?;
    if files.len() > 1 {
        let d = tiles.differences;
        for (k, what, then) in [
            (
                d.crs,
                "coordinate systems",
                "drawn in their own coordinates, nothing reprojected",
            ),
            (d.scales, "scales", "each tile's points at its own scale"),
            (
                d.formats,
                "point formats",
                "each drawn with the attributes it has (elevation where the colour asked for is missing)",
            ),
        ] {
            if k > 1 {
                eprintln!(
                    "warning: {}: the {} tiles have {k} {what}: {then}",
                    a.dataset.display(),
                    files.len()
                );
            }
        }
    }
    let mut samples = tiles.samples;
    let mut even = tiles.even;
    for (b, e) in samples.iter_mut().zip(&mut even) {
        let bound = filter.bind(&b.schema()).map_err(anyhow::Error::msg)?;
        let keep = bound.mask(b);
        *e = keep[..(*e).min(keep.len())].iter().filter(|&&k| k).count();
        b.retain_mask(&keep);
    }
    let overview = samples.first().cloned().unwrap_or_default();
    let colour = a.colour.choose(&overview.schema(), || overview.clone())?;
    let sample =
        myriad_render::preview::Sample::layered(&samples, &even, tiles.detail_share, colour);
    if sample.positions.is_empty() {
        bail!("{}: no points to preview", a.dataset.display());
    }
    let cam = view_of(a, &sample.view, &sample.all)?;
    let img = sample.draw(gpu, raster, &cam, style);
    write_png(&a.output, a.width, a.height, &img)?;
    let of = if files.len() > 1 {
        format!(
            "the {} tiles'",
            myriad_core::units::thousands(files.len() as u64)
        )
    } else {
        "the scan's".into()
    };
    println!(
        "{}: a preview of {} of {of} {} points ({}; {} bytes read), first image after {:.2} s ({}, {:?} path); no dataset built (render without --no-wait builds it)",
        a.output.display(),
        myriad_core::units::thousands(sample.positions.len() as u64),
        myriad_core::units::thousands(tiles.total),
        tiles.how,
        myriad_core::units::thousands(tiles.bytes_read),
        t0.elapsed().as_secs_f64(),
        gpu.name,
        raster.path,
    );
    Ok(())
}

/// The most points a preview reads.
const PREVIEW_POINTS: usize = 1 << 20;

/// The reference image of every point (`--full`) is not one when `damaged` pages are missing.
fn full_image_whole(a: &RenderArgs, damaged: usize) -> Result<()> {
    if a.full && damaged > 0 {
        bail!(
            "{damaged} damaged page{} in {}: {} lacks their points (`myriad verify` lists them)",
            if damaged == 1 { "" } else { "s" },
            a.dataset.display(),
            a.output.display()
        );
    }
    Ok(())
}

/// Warns of each damaged hierarchy page and node page the scene met, naming it; their count.
fn warn_damage(scene: &Scene) -> usize {
    let mut lines: Vec<&String> = scene
        .loader
        .failed_pages()
        .values()
        .chain(scene.loader.failed().values())
        .collect();
    lines.sort();
    lines.dedup();
    for why in &lines {
        eprintln!("warning: {why}");
    }
    lines.len()
}

/// The camera `--view` or `--camera` asks for (default: `view` framed from above at 45
/// degrees), near and far planes around `all`.
fn view_of(a: &RenderArgs, view: &Aabb, all: &Aabb) -> Result<Camera> {
    match a.view.as_deref() {
        Some(v) => {
            let mut cam =
                Camera::view(Some(v), view, all, a.width, a.height).expect("clap checked the view");
            cam.fov_y = a.fov;
            Ok(cam)
        }
        None => camera(view, all, a.camera, a.up, a.width, a.height, a.fov),
    }
}

/// The camera `--camera` asks for, or the data (`view`) framed from above at 45 degrees; near
/// and far planes around everything there is (`all`).
pub fn camera(
    view: &Aabb,
    all: &Aabb,
    eye_target: Option<[f64; 6]>,
    up: [f64; 3],
    width: u32,
    height: u32,
    fov: f64,
) -> Result<Camera> {
    let mut cam = Camera {
        up,
        ..Camera::framing(view, width, height, fov)
    };
    if let Some(c) = eye_target {
        cam.position = [c[0], c[1], c[2]];
        cam.target = [c[3], c[4], c[5]];
        if cam.position == cam.target {
            bail!("--camera: the eye and the target are the same point");
        }
    }
    let (_, _, forward) = cam.basis();
    let side = forward[1] * up[2] - forward[2] * up[1];
    let side2 = forward[2] * up[0] - forward[0] * up[2];
    let side3 = forward[0] * up[1] - forward[1] * up[0];
    if (side * side + side2 * side2 + side3 * side3).sqrt() < 1e-9 {
        bail!("--up is parallel to the view direction: give another --up (e.g. --up 0,1,0)");
    }
    cam.fit_depth(all);
    Ok(cam)
}
