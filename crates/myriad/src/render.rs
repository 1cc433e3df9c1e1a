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
    /// The parallel (orthographic) view: the eye moved back along its line of sight until the
    /// field of view is 1 degree, the view at the target the same size (as the viewers' key 0)
    #[arg(help_heading = "Camera", long, conflicts_with = "stereo")]
    parallel: bool,
    /// Draw a legend over the image: a gradient colouring's colours and range, and in the
    /// parallel view a scale bar
    #[arg(help_heading = "Colour", long, conflicts_with_all = ["stereo", "fly"])]
    legend: bool,
    /// Up direction
    #[arg(help_heading = "Camera", long, value_parser = parse_floats::<3>, default_value = "0,0,1", allow_hyphen_values = true)]
    up: [f64; 3],
    /// Vertical field of view in degrees
    #[arg(help_heading = "Camera", long, default_value_t = 60.0)]
    fov: f64,
    /// Fly a camera path, a frame at each step: a path file ({"views": [{"position": [X,Y,Z],
    /// "target": [X,Y,Z], "time": SECONDS}, ...]}) or the name or number of one kept with the
    /// dataset's saved work (recorded in a viewer); -o names a folder of PNG frames, or a .mp4
    /// (no video encoder is linked: its frames are written beside it with the ffmpeg line that
    /// makes it)
    #[arg(help_heading = "Camera", long = "path", value_name = "FILE|NAME",
          conflicts_with_all = ["stereo", "surface", "no_wait", "camera", "view"])]
    fly: Option<String>,
    /// Draw the view from photo N (from 1) kept with the dataset (`myriad photos`): a pinhole
    /// camera's own (its pose, its field of view, --width wide and as high as its image is
    /// for that width), a panorama's centre column over 90 degrees
    #[arg(help_heading = "Camera", long, value_name = "N",
          conflicts_with_all = ["camera", "view", "fly", "stereo", "parallel"])]
    photo: Option<usize>,
    /// A 360-degree panorama from the camera's eye (equirectangular, --width wide and half as
    /// high), its centre column along the camera's heading: six square views of 90 degrees
    /// resampled; its pose for `myriad photos` (a Potree coordinates.txt line) is printed
    #[arg(help_heading = "Camera", long,
          conflicts_with_all = ["fly", "photo", "stereo", "parallel", "surface", "legend"])]
    panorama: bool,
    /// With --photo: the photo under the points (where no point is drawn, its pixels show)
    #[arg(help_heading = "Camera", long, requires = "photo")]
    over_photo: bool,
    /// With --path: frames a second
    #[arg(
        help_heading = "Camera",
        long,
        default_value_t = 30.0,
        requires = "fly"
    )]
    fps: f64,
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
    let scheme = a.colour.use_scheme(&a.dataset)?;
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
    // The classes the scheme hides are not drawn, unless --classes names them.
    let filter = filter.hiding(&scheme, &ds.meta.schema);
    let options = SelectOptions {
        budget: if a.full { u64::MAX } else { a.budget },
        min_pixels: if a.full { 0.0 } else { a.lod_threshold },
    };
    let mut scene = scene_of(&a, &ds, &filter)?;
    if let Some(p) = &a.fly {
        return render_path(&a, p, (&mut scene, &ds), (&gpu, &raster), &options, &style);
    }
    let mut cam = view_of(&a, &scene.view_bounds, &ds.meta.bounds)?;
    let mut photo = None;
    if let Some(n) = a.photo {
        let (p, file) = crate::photos::photo(&dataset, n)?;
        let v = p.view().ok_or_else(|| {
            anyhow::anyhow!(
                "--photo {n}: \"{}\" is not placed (a {} image): no view to draw from",
                p.name,
                p.kind_name()
            )
        })?;
        let height = (a.width as f64 * p.height as f64 / p.width as f64)
            .round()
            .max(1.0);
        if height > 16384.0 {
            bail!(
                "--photo {n}: {}x{} at --width {}: {height} pixels high, at most 16384 (a smaller --width)",
                p.width,
                p.height,
                a.width
            );
        }
        let height = height as u32;
        let eye_target = [
            v.eye[0],
            v.eye[1],
            v.eye[2],
            v.target[0],
            v.target[1],
            v.target[2],
        ];
        cam = camera(
            &scene.view_bounds,
            &ds.meta.bounds,
            Some(eye_target),
            v.up,
            a.width,
            height,
            v.fov_y,
        )?;
        photo = Some((p, file));
    }
    if a.parallel {
        cam = parallel(cam, &ds.meta.bounds);
    }
    if a.panorama {
        return render_panorama(
            &a,
            (&mut scene, &ds),
            (&gpu, &raster),
            &cam,
            &options,
            &style,
        );
    }
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
    let mut image = still.image;
    if a.legend {
        legend(&a, &scene, &ds, &cam, &mut image);
    }
    if let (Some((p, file)), true) = (&photo, a.over_photo) {
        under_photo(p, file, &mut image, &cam)?;
    }
    write_png(&a.output, cam.width, cam.height, &image)?;
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
    let ext = (a.output.extension()).map(|e| e.to_string_lossy().to_ascii_lowercase());
    match (&a.fly, ext.as_deref()) {
        (None, Some("png")) | (Some(_), None | Some("mp4")) => {}
        (None, _) => bail!("{}: render writes a PNG image (.png)", a.output.display()),
        (Some(_), _) => bail!(
            "{}: render --path writes a folder of frames (a name without an extension) or a .mp4",
            a.output.display()
        ),
    }
    if !(a.fps > 0.0 && a.fps <= 1000.0) {
        bail!("--fps must be above 0 and at most 1000");
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

/// `render --panorama`: six views of 90 degrees from `cam`'s eye (ahead, left, behind, right,
/// up, down of its heading), each drawn as a still, resampled to an equirectangular image:
/// column c at azimuth 180 - 360 (c + 0.5) / width degrees from the heading (counterclockwise),
/// row r at elevation 90 - 180 (r + 0.5) / height.
fn render_panorama(
    a: &RenderArgs,
    (scene, ds): (&mut Scene, &Dataset),
    (gpu, raster): (&Gpu, &Rasterizer),
    cam: &Camera,
    options: &SelectOptions,
    style: &Style,
) -> Result<()> {
    let (w, h) = (a.width.max(8), (a.width / 2).max(4));
    let side = (w / 4).max(64);
    let heading = (cam.target[1] - cam.position[1]).atan2(cam.target[0] - cam.position[0]);
    let e = cam.position;
    let (c, s) = (heading.cos(), heading.sin());
    // The panorama's frame (x ahead, y left, z up) in the dataset's axes.
    let world = |d: [f64; 3]| [c * d[0] - s * d[1], s * d[0] + c * d[1], d[2]];
    let ahead = world([1.0, 0.0, 0.0]);
    let faces: Vec<([f64; 3], [f64; 3])> = [
        [1.0, 0.0, 0.0],
        [-1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, -1.0, 0.0],
        [0.0, 0.0, 1.0],
        [0.0, 0.0, -1.0],
    ]
    .iter()
    .map(|&d| (world(d), if d[2] == 0.0 { [0.0, 0.0, 1.0] } else { ahead }))
    .collect();
    let t0 = Instant::now();
    let mut views = Vec::new();
    for (dir, up) in &faces {
        let target = [e[0] + dir[0], e[1] + dir[1], e[2] + dir[2]];
        let mut face = Camera {
            position: e,
            target,
            up: *up,
            fov_y: 90.0,
            width: side,
            height: side,
            ..*cam
        };
        face.fit_depth(&ds.meta.bounds);
        let still = myriad_render::still::draw(scene, gpu, raster, &face, options, style, None, t0);
        views.push((face, still.image));
    }
    ds.check_unchanged()?;
    let mut out = vec![0u8; (w * h * 4) as usize];
    for r in 0..h {
        let el = std::f64::consts::FRAC_PI_2 - (r as f64 + 0.5) / h as f64 * std::f64::consts::PI;
        for col in 0..w {
            let az = std::f64::consts::PI - (col as f64 + 0.5) / w as f64 * std::f64::consts::TAU;
            let d = world([el.cos() * az.cos(), el.cos() * az.sin(), el.sin()]);
            // The face looking most along the ray, and its pixel there.
            let best = (views.iter())
                .map(|(f, img)| (f.to_eye([e[0] + d[0], e[1] + d[1], e[2] + d[2]]), f, img))
                .max_by(|x, y| x.0[2].total_cmp(&y.0[2]));
            let Some((q, f, img)) = best else { continue };
            let focal = f.focal();
            let x = (side as f64 / 2.0 + q[0] * focal / q[2])
                .floor()
                .clamp(0.0, side as f64 - 1.0) as u32;
            let y = (side as f64 / 2.0 - q[1] * focal / q[2])
                .floor()
                .clamp(0.0, side as f64 - 1.0) as u32;
            let from = ((y * side + x) * 4) as usize;
            let to = ((r * w + col) * 4) as usize;
            out[to..to + 4].copy_from_slice(&img[from..from + 4]);
        }
    }
    write_png(&a.output, w, h, &out)?;
    let damaged = warn_damage(scene);
    println!(
        "{}: a panorama of {w}x{h} from {:.3}, {:.3}, {:.3} (six views of {side}x{side}), drawn in {:.1} s",
        a.output.display(),
        e[0],
        e[1],
        e[2],
        t0.elapsed().as_secs_f64()
    );
    // Its line of a Potree panorama list: file, time, x, y, z, course (clockwise from +y), pitch, roll.
    let course = (90.0 - heading.to_degrees()).rem_euclid(360.0);
    let name = a
        .output
        .file_name()
        .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
    println!(
        "coordinates.txt: {name}\t0\t{}\t{}\t{}\t{course}\t0\t0",
        e[0], e[1], e[2]
    );
    full_image_whole(a, damaged)
}

/// `--over-photo`: the pixels where no point was drawn (the background) take the photo's
/// along their rays (`Photo::project`: a pinhole photo's principal point honoured, a
/// panorama's direction looked up).
fn under_photo(
    p: &myriad_measure::photos::Photo,
    file: &std::path::Path,
    image: &mut [u8],
    cam: &Camera,
) -> Result<()> {
    let img = image::open(file)
        .map_err(|e| anyhow::anyhow!("{}: {e}", file.display()))?
        .to_rgba8();
    let (iw, ih) = img.dimensions();
    // The photo's pixels are the list's; an image of another size is scaled to them.
    let (sx, sy) = (iw as f64 / p.width as f64, ih as f64 / p.height as f64);
    let (r, u, f) = cam.basis();
    let focal = cam.focal();
    for y in 0..cam.height {
        for x in 0..cam.width {
            let at = ((y * cam.width + x) * 4) as usize;
            if image[at..at + 4] != [0, 0, 0, 255] {
                continue;
            }
            let dx = (x as f64 + 0.5 - cam.width as f64 / 2.0) / focal;
            let dy = -(y as f64 + 0.5 - cam.height as f64 / 2.0) / focal;
            let q: [f64; 3] =
                std::array::from_fn(|i| cam.position[i] + f[i] + r[i] * dx + u[i] * dy);
            let Some([c, row]) = p.project(q) else {
                continue;
            };
            let (c, row) = ((c * sx).floor(), (row * sy).floor());
            if c >= 0.0 && row >= 0.0 && c < iw as f64 && row < ih as f64 {
                let px = img.get_pixel(c as u32, row as u32);
                image[at..at + 3].copy_from_slice(&px.0[..3]);
            }
        }
    }
    Ok(())
}

/// The field of view of the parallel view, in degrees (the viewers' too).
const PARALLEL_FOV: f64 = 1.0;

/// `cam` as a parallel view: the eye moved back along its line of sight until the field of
/// view is [`PARALLEL_FOV`], the view at the target the same size; near and far around `all`.
fn parallel(mut cam: Camera, all: &Aabb) -> Camera {
    let v: [f64; 3] = std::array::from_fn(|i| cam.position[i] - cam.target[i]);
    let d = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt().max(1e-9);
    let half = d * (cam.fov_y.to_radians() / 2.0).tan();
    let far = half / (PARALLEL_FOV.to_radians() / 2.0).tan();
    cam.position = std::array::from_fn(|i| cam.target[i] + v[i] * far / d);
    cam.fov_y = PARALLEL_FOV;
    cam.fit_depth(all);
    cam
}

/// `--legend`: a gradient colouring's legend; in the parallel view, a scale bar.
fn legend(a: &RenderArgs, scene: &Scene, ds: &Dataset, cam: &Camera, image: &mut [u8]) {
    use myriad_render::legend::{Canvas, gradient_legend, scale_bar};
    let mut c = Canvas {
        width: cam.width,
        height: cam.height,
        px: image,
    };
    if let myriad_render::ColorBy::Ramp(r) = scene.colour() {
        let name = match r.column {
            myriad_core::Column::AboveGround(_) => "height above ground".to_string(),
            col => (myriad_core::Column::columns(&ds.meta.schema).into_iter())
                .find(|(_, c)| *c == col)
                .map_or_else(|| a.colour.colour.clone(), |(n, _)| n),
        };
        gradient_legend(&mut c, r.gradient, r.range, &name);
    }
    if a.parallel {
        let d: f64 = (0..3)
            .map(|i| (cam.position[i] - cam.target[i]).powi(2))
            .sum::<f64>()
            .sqrt();
        let per_pixel = 2.0 * d * (cam.fov_y.to_radians() / 2.0).tan() / cam.height as f64;
        let units = myriad_measure::measurement::crs_units(ds.meta.crs.as_deref());
        scale_bar(&mut c, per_pixel, units);
    }
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

/// The most frames `render --path` writes.
const MAX_FRAMES: usize = 1_000_000;

/// A camera path file, read; an error names it and the line or member.
pub fn read_path(f: &std::path::Path) -> Result<myriad_measure::camera_path::CameraPath> {
    let max = myriad_measure::camera_path::MAX_BYTES;
    let text = crate::measure::read_text(f, max, "a camera path")?;
    myriad_measure::camera_path::CameraPath::parse(&text)
        .map_err(|e| anyhow::anyhow!("{}: {e}", f.display()))
}

/// The camera path of saved work by its name or its number (from 1).
pub fn saved_path(
    w: &myriad_measure::work::Work,
    name: &str,
) -> std::result::Result<myriad_measure::camera_path::CameraPath, String> {
    let by_number = name.parse::<usize>().ok().and_then(|i| i.checked_sub(1));
    (w.paths.iter().find(|p| p.name == name))
        .or_else(|| by_number.and_then(|i| w.paths.get(i)))
        .cloned()
        .ok_or_else(|| {
            let names: Vec<String> = (w.paths.iter().enumerate())
                .map(|(i, p)| format!("{} \"{}\"", i + 1, p.name))
                .collect();
            match names.len() {
                0 => "no such file, and the saved work keeps no camera path".to_string(),
                _ => format!(
                    "no such file, nor a camera path of the saved work ({})",
                    names.join(", ")
                ),
            }
        })
}

/// Whether `dir` holds only frames (`NNNNN.png`): what `render --path --force` replaces.
fn only_frames(dir: &std::path::Path) -> bool {
    std::fs::read_dir(dir).is_ok_and(|entries| {
        entries.flatten().all(|e| {
            let n = e.file_name().to_string_lossy().into_owned();
            n.strip_suffix(".png")
                .is_some_and(|d| !d.is_empty() && d.bytes().all(|b| b.is_ascii_digit()))
        })
    })
}

/// `render --path`: the path flown at `--fps`, a frame a step, each drawn as a still (the
/// selection settled within the budget, the passes run), into a folder that appears whole.
fn render_path(
    a: &RenderArgs,
    given: &str,
    (scene, ds): (&mut Scene, &Dataset),
    (gpu, raster): (&Gpu, &Rasterizer),
    options: &SelectOptions,
    style: &Style,
) -> Result<()> {
    let file = std::path::Path::new(given);
    let path = if file.is_file() {
        read_path(file)?
    } else {
        let sidecar = myriad_measure::work::sidecar_for(&a.dataset);
        let w = myriad_measure::files::load_work(&sidecar, None)?;
        saved_path(&w, given).map_err(|e| anyhow::anyhow!("--path {given}: {e}"))?
    };
    let count = (path.duration() * a.fps + 1e-9).floor() + 1.0;
    if count > MAX_FRAMES as f64 {
        bail!(
            "--path {given}: {count} frames at {} fps: at most {MAX_FRAMES}",
            a.fps
        );
    }
    let views = path.frames(a.fps);
    let video = (a.output.extension()).is_some_and(|e| e.eq_ignore_ascii_case("mp4"));
    let folder = if video {
        a.output.with_extension("frames")
    } else {
        a.output.clone()
    };
    myriad_io::atomic::refuse_input_as_output(&folder, &[&a.dataset])?;
    let out =
        myriad_io::atomic::AtomicDir::create(&folder, a.force, only_frames, "a folder of frames")?;
    let t0 = Instant::now();
    let mut points = Vec::with_capacity(views.len());
    for (i, v) in views.iter().enumerate() {
        let eye_target = [
            v.position[0],
            v.position[1],
            v.position[2],
            v.target[0],
            v.target[1],
            v.target[2],
        ];
        let cam = camera(
            &scene.view_bounds,
            &ds.meta.bounds,
            Some(eye_target),
            a.up,
            a.width,
            a.height,
            a.fov,
        )
        .map_err(|e| anyhow::anyhow!("--path {given}: frame {i}: {e}"))?;
        let still = myriad_render::still::draw(scene, gpu, raster, &cam, options, style, None, t0);
        write_png(
            &out.temp().join(format!("{i:05}.png")),
            a.width,
            a.height,
            &still.image,
        )?;
        points.push(still.stats.points);
    }
    ds.check_unchanged()?;
    out.commit()?;
    let damaged = warn_damage(scene);
    points.sort_unstable();
    println!(
        "{}: {} frames of {}x{} ({:.2} s at {} fps, camera path \"{}\"), median {} points a frame, drawn in {:.1} s ({}, {:?} path)",
        folder.display(),
        views.len(),
        a.width,
        a.height,
        path.duration(),
        a.fps,
        path.name,
        myriad_core::units::thousands(points[points.len() / 2]),
        t0.elapsed().as_secs_f64(),
        gpu.name,
        raster.path,
    );
    if video {
        // yuv420p wants even sides.
        let pad = if a.width % 2 == 1 || a.height % 2 == 1 {
            " -vf pad=ceil(iw/2)*2:ceil(ih/2)*2"
        } else {
            ""
        };
        println!(
            "no video encoder is linked into myriad; make {} from the frames with:\nffmpeg -framerate {} -i {}/%05d.png{pad} -c:v libx264 -pix_fmt yuv420p -crf 18 {}",
            a.output.display(),
            a.fps,
            folder.display(),
            a.output.display()
        );
    }
    full_image_whole(a, damaged)
}
