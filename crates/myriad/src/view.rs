//! `myriad view DATASET...`: the interactive viewer (crate myriad-viewer).

use anyhow::{Context, Result, bail};
use clap::Args;
use myriad_build::open::{Opened, Opener, Pending, Preview, Watched};
use myriad_core::units::parse_floats;
use myriad_format::Dataset;
use myriad_measure::shape::Want;
use myriad_render::args::{parse_point_size, parse_shape};
use myriad_render::{Edl, Passes, PointSize, Shape, Style};
use myriad_viewer::ViewOptions;
use std::path::PathBuf;
use std::sync::Arc;

#[derive(Args)]
pub struct ViewArgs {
    /// Datasets (.myr), shown together; a scan or a folder of LAS/LAZ tiles is converted once
    /// into a dataset kept next to it
    #[arg(required = true)]
    datasets: Vec<PathBuf>,
    /// Window size in pixels
    #[arg(long, default_value_t = 1280)]
    width: u32,
    #[arg(long, default_value_t = 800)]
    height: u32,
    /// Eye and target: EX,EY,EZ,TX,TY,TZ [default: the data from above at 45 degrees]
    #[arg(help_heading = "Camera", long, value_parser = parse_floats::<6>, allow_hyphen_values = true)]
    camera: Option<[f64; 6]>,
    /// Vertical field of view in degrees
    #[arg(help_heading = "Camera", long, default_value_t = 60.0)]
    fov: f64,
    /// Open in an axis view: top, front, right, bottom, back or left (keys 1 to 6)
    #[arg(help_heading = "Camera", long, value_parser = parse_view, conflicts_with = "camera")]
    view: Option<myriad_viewer::nav::View>,
    /// Open in the parallel (orthographic) view (key 0)
    #[arg(help_heading = "Camera", long)]
    parallel: bool,
    /// Open with the profile along this section line cut: X1,Y1,X2,Y2[,...] or @FILE (key X
    /// draws one)
    #[arg(
        help_heading = "Tools",
        long,
        value_name = "LINE",
        allow_hyphen_values = true
    )]
    section: Option<String>,
    /// With --section: the corridor's width [default: four times the points' spacing]
    #[arg(help_heading = "Tools", long, requires = "section")]
    section_width: Option<f64>,
    /// Open measuring the volume over this polygon: X1,Y1,X2,Y2,X3,Y3[,...] or @FILE
    /// (GeoJSON, WKT or CSV; key V draws one); the result is printed too
    #[arg(
        help_heading = "Tools",
        long,
        value_name = "POLYGON",
        allow_hyphen_values = true
    )]
    volume: Option<String>,
    /// With --volume: rim (the plane fitted to the rim's points) or an elevation
    #[arg(
        help_heading = "Tools",
        long,
        requires = "volume",
        default_value = "rim",
        allow_hyphen_values = true
    )]
    volume_base: String,
    /// With --volume: the grid's cell size [default: about twice the points' spacing]
    #[arg(help_heading = "Tools", long, requires = "volume")]
    volume_cell: Option<f64>,
    /// Open making this edit of the first dataset, as the edit tool makes one (key K): the
    /// points in the polygon given a class, or removed: X1,Y1,X2,Y2,X3,Y3[,...]=CLASS or
    /// =remove (a polygon @FILE too); repeat for more, made in order
    #[arg(
        help_heading = "Tools",
        long,
        value_name = "POLYGON=CLASS",
        allow_hyphen_values = true
    )]
    classify: Vec<String>,
    /// Then undo this many of its edits (as Ctrl+Z does)
    #[arg(help_heading = "Tools", long, default_value_t = 0,
          value_parser = clap::value_parser!(u32).range(0..=10_000))]
    undo_edits: u32,
    /// Open with the contours of the terrain `myriad ground` found, every INTERVAL (the panel's
    /// "contours every"); their count is printed
    #[arg(help_heading = "Tools", long, value_name = "INTERVAL")]
    contours: Option<f64>,
    /// Add this view to the camera path being recorded (as key J does): EX,EY,EZ,TX,TY,TZ
    /// (repeatable, in order, 2 s apart)
    #[arg(help_heading = "Camera path", long, value_parser = parse_floats::<6>, allow_hyphen_values = true, value_name = "EYE,TARGET")]
    path_view: Vec<[f64; 6]>,
    /// Save the views recorded as the camera path NAME with the saved work (the panel's "save")
    #[arg(
        help_heading = "Camera path",
        long,
        value_name = "NAME",
        requires = "path_view"
    )]
    record_path: Option<String>,
    /// A map beside the view: footprint, camera and view cone on tiles from this address
    /// template, as https://tile.example/{z}/{x}/{y}.png (XYZ; {-y} for TMS, WMTS's
    /// {TileMatrix}/{TileCol}/{TileRow}); none is built in
    #[arg(long, value_name = "TEMPLATE")]
    map_tiles: Option<String>,
    /// Open photo N (from 1) kept with the first dataset (`myriad photos`): the camera at its
    /// pose, the photo over the view (a panorama as a sphere around the eye)
    #[arg(long, value_name = "N")]
    photo: Option<usize>,
    /// Play a camera path once the view is in: a path file, or the name or number of one
    /// kept with the saved work
    #[arg(help_heading = "Camera path", long, value_name = "FILE|NAME")]
    play_path: Option<String>,
    /// Most points drawn, shared by all datasets
    #[arg(long, value_parser = myriad_core::units::parse_count, default_value = "2M")]
    budget: u64,
    /// Point size: fixed:PX, adaptive or adaptive:SCALE
    #[arg(help_heading = "Points and passes", long, value_parser = parse_point_size, default_value = "adaptive")]
    point_size: PointSize,
    /// Point shape: square, round, paraboloid
    #[arg(help_heading = "Points and passes", long, value_parser = parse_shape, default_value = "square")]
    shape: Shape,
    /// Post passes: fill, shade, ssao, edl, blur, aa, or none (as render's; also checkboxes
    /// in the window)
    #[arg(help_heading = "Points and passes", long, value_parser = myriad_render::args::parse_passes, default_value = myriad_render::DEFAULT_PASSES)]
    passes: Passes,
    /// Eye-dome lighting: adds edl to --passes
    #[arg(long)]
    edl: bool,
    #[command(flatten, next_help_heading = "Colour")]
    colour: crate::measure::ColourArgs,
    #[command(flatten, next_help_heading = "Filters")]
    filter: crate::measure::FilterArgs,
    /// Draw on the window's GPU adapter (with --vr: the runtime's) even where it is a software
    /// one (lavapipe); without it, a software adapter leaves the drawing to the CPU path
    #[arg(help_heading = "Points and passes", long)]
    gpu: bool,
    /// On a GPU: read each frame back and upload it, instead of drawing into the window's
    /// texture (for comparing frame intervals)
    #[arg(help_heading = "Testing", long)]
    readback: bool,
    /// Once the view has converged, write the window to this PNG
    #[arg(help_heading = "Testing", long)]
    screenshot: Option<PathBuf>,
    /// Close the window after the screenshot
    #[arg(help_heading = "Testing", long, requires = "screenshot")]
    exit_after_converged: bool,
    /// Scripted navigation before converging: orbit for this many frames and print the frame
    /// times seen while moving
    #[arg(help_heading = "Testing", long, default_value_t = 0)]
    orbit_frames: u32,
    /// Hold this frame rate by adjusting the point budget each frame (--budget is then the
    /// most it may grow to); 0: a fixed budget [default: 30; 90 with --stereo, a headset's rate]
    #[arg(help_heading = "Level of detail and pacing", long)]
    target_fps: Option<f64>,
    /// Fraction of the view's width and height drawn while the camera moves (from 0.1 to 1;
    /// at rest always the full resolution and the whole --budget) [default: 0.5 on the CPU
    /// path, 1 on a GPU]
    #[arg(help_heading = "Level of detail and pacing", long)]
    moving_scale: Option<f32>,
    /// Cull nodes hidden behind nearer ones: checked (the software test, each cull checked by
    /// an occlusion query after the frame: a node that shows is drawn from the next frame),
    /// software (the test alone), queries (occlusion queries after each frame, acting from the
    /// next) or off
    #[arg(help_heading = "Level of detail and pacing", long, value_parser = myriad_lod::Occlusion::parse, default_value = "checked")]
    occlusion: myriad_lod::Occlusion,
    /// Pixels a level's point spacing must cover to be drawn
    #[arg(help_heading = "Level of detail and pacing", long, value_parser = myriad_render::args::parse_lod_threshold, default_value = "1")]
    lod_threshold: f64,
    /// Show the surface the points make: quads, boxes or splats; the panel switches
    #[arg(help_heading = "Surface", long, value_parser = myriad_render::surface::Kind::parse)]
    surface: Option<myriad_render::surface::Kind>,
    #[command(flatten, next_help_heading = "Surface")]
    surface_options: myriad_render::args::SurfaceArgs,
    /// Both eyes side by side, from the first dataset, for a check without a headset
    #[arg(help_heading = "Stereo and VR", long)]
    stereo: bool,
    /// With --stereo: the distance between the eyes, in the dataset's units
    #[arg(
        help_heading = "Stereo and VR",
        long,
        default_value_t = 0.064,
        requires = "stereo"
    )]
    ipd: f64,
    /// In a headset through OpenXR (the first dataset, in front of you at the stage's origin)
    #[arg(help_heading = "Stereo and VR", long, conflicts_with_all = ["stereo", "screenshot"])]
    vr: bool,
    /// With --vr: end the session after this many frames (scripts, tests)
    #[arg(help_heading = "Stereo and VR", long, requires = "vr")]
    vr_frames: Option<u64>,
    /// With --vr: metres a data unit is shown at
    #[arg(
        help_heading = "Stereo and VR",
        long,
        default_value_t = 1.0,
        requires = "vr"
    )]
    vr_scale: f64,
}

fn parse_view(s: &str) -> Result<myriad_viewer::nav::View, String> {
    use myriad_viewer::nav::View;
    View::ALL
        .into_iter()
        .find(|v| v.name() == s)
        .ok_or_else(|| {
            let names: Vec<&str> = View::ALL.iter().map(|v| v.name()).collect();
            format!("{s}: one of {}", names.join(", "))
        })
}

pub fn run(a: ViewArgs) -> Result<()> {
    let target_fps = check(&a)?;
    let mut opener = Opener::new(if a.vr {
        Preview::None
    } else {
        Preview::Dataset
    });
    let Layers {
        datasets,
        to_build,
        watched,
    } = open_layers(&a, &mut opener)?;
    // The class scheme: --classes-scheme, else the first dataset's saved one.
    if let Some(first) = a.datasets.first() {
        a.colour.use_scheme(first)?;
    }
    if a.vr {
        return run_vr(&a, datasets);
    }
    if let Some(c) = a.camera
        && c[..3] == c[3..]
    {
        bail!("--camera: the eye and the target are the same point");
    }
    // The first dataset's annotations and measurements, kept beside what was given.
    let work = (a.datasets.first())
        .filter(|p| !myriad_format::remote::is_url(p))
        .map(|p| myriad_measure::work::sidecar_for(p));
    let options = ViewOptions {
        work,
        view: a.view,
        parallel: a.parallel,
        volume: volume_asked(&a, &datasets)?,
        section: section_asked(&a, &datasets)?,
        edits: Some(edits_asked(&a, &datasets)?),
        paths: Some(paths_asked(&a)?),
        photo: a.photo,
        map_tiles: match &a.map_tiles {
            Some(t) => {
                myriad_measure::map::check_template(t)
                    .map_err(|e| anyhow::anyhow!("--map-tiles {e}"))?;
                Some(t.clone())
            }
            None => None,
        },
        contours: match a.contours {
            Some(i) if !(i.is_finite() && i > 0.0) => bail!("--contours {i}: a positive interval"),
            c => c,
        },
        width: a.width,
        height: a.height,
        camera: a.camera.map(|c| ([c[0], c[1], c[2]], [c[3], c[4], c[5]])),
        fov: a.fov,
        budget: a.budget,
        style: Style {
            size: a.point_size,
            shape: a.shape,
            passes: Passes {
                edl: a.passes.edl.or(a.edl.then(Edl::default)),
                ..a.passes
            },
            background: [0, 0, 0, 255],
            clip: None,
        },
        colour: match datasets.first() {
            Some((_, ds)) => a.colour.for_dataset(ds)?,
            None => myriad_render::ColorBy::Rgb,
        },
        filter: a.filter.filter()?,
        screenshot: a.screenshot,
        exit_after_converged: a.exit_after_converged,
        orbit_frames: a.orbit_frames,
        gpu: a.gpu,
        readback: a.readback,
        target_fps: (target_fps > 0.0).then_some(target_fps),
        moving_scale: a.moving_scale,
        occlusion: a.occlusion,
        lod_threshold: a.lod_threshold,
        surface: a
            .surface
            .map(|k| a.surface_options.surface(k))
            .transpose()
            .map_err(anyhow::Error::msg)?,
        stereo: match a.stereo {
            true if !(a.ipd >= 0.0 && a.ipd.is_finite()) => {
                bail!("--ipd must be a distance of 0 or more")
            }
            stereo => stereo.then_some(a.ipd),
        },
        builds: (!watched.is_empty()).then(|| {
            // One build at a time, on a thread of its own: builds in one process share its
            // scratch names, and the cores are the viewer's too. Then every scan shown is
            // watched: one that changes on disk (size, modification time) is built again and
            // replaces what is shown.
            let (tx, rx) = std::sync::mpsc::channel();
            let n = to_build.len();
            let running = myriad_viewer::builds::Running::default();
            let r = running.clone();
            let watched = Watched::new(watched);
            std::thread::spawn(move || watch(to_build, watched, tx, r));
            myriad_viewer::Builds::new(rx, n, running)
        }),
    };
    let shown = myriad_viewer::run(datasets, options).map_err(anyhow::Error::msg);
    drop(opener);
    shown
}

/// The options' values checked before anything is opened; the frame rate to keep (0: off).
fn check(a: &ViewArgs) -> Result<f64> {
    if !(a.fov > 0.0 && a.fov < 180.0) {
        bail!("--fov must be between 0 and 180 degrees");
    }
    if a.width < 64 || a.height < 64 || a.width > 16384 || a.height > 16384 {
        bail!("--width and --height must be 64 to 16384");
    }
    let target_fps = a.target_fps.unwrap_or(if a.stereo { 90.0 } else { 30.0 });
    if a.moving_scale.is_some_and(|s| !(0.1..=1.0).contains(&s)) {
        bail!("--moving-scale must be from 0.1 to 1");
    }
    if !(target_fps == 0.0 || (1.0..=240.0).contains(&target_fps)) {
        bail!("--target-fps must be 0 (off) or from 1 to 240");
    }
    Ok(target_fps)
}

/// The layers a window shows, and the scans behind them.
struct Layers {
    /// Each layer's name and dataset (a scan's preview until its dataset is built).
    datasets: Vec<(String, Arc<Dataset>)>,
    /// The scans shown from their previews, to build, by layer.
    to_build: Vec<(usize, Pending)>,
    /// The layers that show a scan (not a dataset), to watch for changes.
    watched: Vec<(usize, PathBuf)>,
}

/// The inputs opened as layers.
fn open_layers(a: &ViewArgs, opener: &mut Opener) -> Result<Layers> {
    // A LAS/LAZ scan (or folder of tiles) without its dataset shows its preview at once while
    // its dataset is built behind it (not in VR, which converts first); every layer that shows
    // a scan (not a dataset) is watched for changes while the window is open.
    let (mut datasets, mut to_build, mut watched) = (Vec::new(), Vec::new(), Vec::new());
    for (i, p) in a.datasets.iter().enumerate() {
        let name = p.file_name().map_or_else(
            || p.display().to_string(),
            |n| n.to_string_lossy().to_string(),
        );
        if !a.vr && !myriad_build::open::is_dataset(p) {
            watched.push((i, p.clone()));
        }
        match crate::cached::open(opener, p)? {
            Opened::Dataset(d) => datasets.push((name, Arc::new(Dataset::open(&d)?))),
            Opened::Preview(pending) => {
                let preview = (pending.preview.as_ref()).context("a preview without a dataset")?;
                eprintln!(
                    "{}: showing its preview while its dataset is built",
                    p.display()
                );
                let ds = Arc::new(Dataset::open(preview)?);
                datasets.push((format!("{name} (preview)"), ds));
                to_build.push((i, pending));
            }
        }
    }
    Ok(Layers {
        datasets,
        to_build,
        watched,
    })
}

/// `view --vr`: the first dataset in a headset (OpenXR), and what the session did.
fn run_vr(a: &ViewArgs, mut datasets: Vec<(String, Arc<Dataset>)>) -> Result<()> {
    if !(a.vr_scale > 0.0 && a.vr_scale.is_finite()) {
        bail!("--vr-scale must be above 0");
    }
    let o = myriad_viewer::vr::VrOptions {
        frames: a.vr_frames,
        budget: a.budget,
        style: Style {
            size: a.point_size,
            shape: a.shape,
            passes: a.passes,
            background: [0, 0, 0, 255],
            clip: None,
        },
        scale: a.vr_scale,
        gpu: a.gpu,
    };
    let ds = datasets.swap_remove(0).1;
    let r = myriad_viewer::vr::run(ds, &o).map_err(|e| anyhow::anyhow!("--vr: {e}"))?;
    print_vr(&r);
    Ok(())
}

/// The VR session's report: frames, intervals, head motion, budget, controllers, the
/// swapchain's check and the hidden-area mesh.
fn print_vr(r: &myriad_viewer::vr::VrReport) {
    let mut iv = r.intervals.clone();
    iv.sort_by(f64::total_cmp);
    let median = iv.get(iv.len() / 2).copied().unwrap_or(0.0);
    let moved = r.heads.windows(2).filter(|p| p[0] != p[1]).count();
    let mut periods = r.periods.clone();
    periods.sort_by(f64::total_cmp);
    let period = periods.get(periods.len() / 2).copied().unwrap_or(0.0);
    let mut work = r.work.clone();
    work.sort_by(f64::total_cmp);
    let work = work.get(work.len() / 2).copied().unwrap_or(0.0);
    println!(
        "vr: session {}, {} frames submitted with {} views each ({}x{}), median interval {median:.1} ms (the runtime's display period {period:.1} ms; a frame's work {work:.1} ms), head moved between {moved} of them, the image changed in {} of {} looked at, budget settled on {} points, controllers located in {} frames, {} points measured{}, {}",
        if r.focused {
            "reached FOCUSED"
        } else {
            "never focused"
        },
        r.frames,
        r.views,
        r.size.0,
        r.size.1,
        r.changed,
        r.checked.saturating_sub(1),
        r.budget,
        r.hands,
        r.measured.len(),
        r.measured
            .windows(2)
            .last()
            .map(|p| {
                let d: f64 = (0..3).map(|a| (p[1][a] - p[0][a]).powi(2)).sum();
                format!(" (the last two {:.3} apart)", d.sqrt())
            })
            .unwrap_or_default(),
        if r.ended { "ended cleanly" } else { "lost" },
    );
    println!(
        "vr: {}; the swapchain images of every {}th frame differ from it in {} pixels",
        r.device,
        myriad_viewer::vr::CHECK_EVERY,
        r.swapchain_differ
    );
    match r.hidden {
        Some([l, rt]) => println!(
            "vr: the runtime's hidden-area mesh masks {l} and {rt} of each eye's {} pixels ({} of them lit in every {}th frame)",
            r.size.0 as u64 * r.size.1 as u64,
            r.hidden_lit,
            myriad_viewer::vr::CHECK_EVERY
        ),
        None => println!("vr: the runtime gives no hidden-area mesh (XR_KHR_visibility_mask)"),
    }
}

/// A polygon or line argument (inline or @FILE), a file's checked against the first dataset.
fn shape_arg(
    s: &str,
    what: &str,
    want: Want,
    datasets: &[(String, Arc<Dataset>)],
) -> Result<Vec<[f64; 2]>> {
    let shape = myriad_measure::files::xy_arg(s, what, want).map_err(anyhow::Error::msg)?;
    if let Some((_, ds)) = datasets.first() {
        myriad_measure::files::check_shape(
            &shape,
            s,
            what,
            ds.meta.crs.as_deref(),
            &ds.meta.bounds,
        )
        .map_err(anyhow::Error::msg)?;
    }
    Ok(shape.points)
}

/// The dataset the edit tool edits (the first given, where it is a dataset on this disk: a
/// scan's is rebuilt under another name when it changes, one on the web is not ours to edit),
/// and `--classify` and `--undo-edits`, checked.
fn edits_asked(
    a: &ViewArgs,
    datasets: &[(String, Arc<Dataset>)],
) -> Result<myriad_viewer::EditsAsked> {
    use myriad_measure::edits::{Action, Area, Change, Edit};
    let dataset = match a.datasets.first() {
        None => Err("no dataset".to_string()),
        Some(p) if myriad_format::remote::is_url(p) => Err(format!(
            "{}: edits are kept beside a dataset on this machine's disk",
            p.display()
        )),
        Some(p) if !myriad_build::open::is_dataset(p) => Err(format!(
            "{}: a scan: convert it first (`myriad convert`) so that its edits have a dataset \
             to stay beside",
            p.display()
        )),
        Some(_) => Ok(datasets[0].1.path().to_path_buf()),
    };
    let mut changes = Vec::new();
    for c in &a.classify {
        let Some((polygon, to)) = c.rsplit_once('=') else {
            bail!("--classify \"{c}\": POLYGON=CLASS or POLYGON=remove");
        };
        let ring = shape_arg(polygon, "--classify", Want::Polygon, datasets)?;
        let action = match to.trim() {
            "remove" => Action::Remove,
            t => match myriad_measure::Filter::parse_classes(t).map_err(anyhow::Error::msg)?[..] {
                [one] => Action::Class(one),
                _ => bail!("--classify \"{c}\": one class after ="),
            },
        };
        changes.push(Change::Add(Edit {
            area: Area::Polygon { ring, z: None },
            classes: None,
            wheres: Vec::new(),
            action,
        }));
    }
    changes.extend((0..a.undo_edits).map(|_| Change::Undo));
    if let (Err(m), false) = (&dataset, changes.is_empty()) {
        bail!("--classify: {m}");
    }
    Ok(myriad_viewer::EditsAsked { dataset, changes })
}

/// `--path-view`, `--record-path` and `--play-path`, checked (a path to play read).
fn paths_asked(a: &ViewArgs) -> Result<myriad_viewer::PathsAsked> {
    let mut views = Vec::new();
    for v in &a.path_view {
        if v[..3] == v[3..] {
            bail!("--path-view: the eye and the target are the same point");
        }
        views.push(myriad_measure::camera_path::View {
            position: [v[0], v[1], v[2]],
            target: [v[3], v[4], v[5]],
        });
    }
    let recorded = a.play_path.is_some() && a.play_path == a.record_path;
    let play = match &a.play_path {
        None => None,
        Some(_) if recorded => None,
        Some(p) if std::path::Path::new(p).is_file() => {
            Some(crate::render::read_path(std::path::Path::new(p))?)
        }
        Some(p) => {
            let first = a
                .datasets
                .first()
                .filter(|d| !myriad_format::remote::is_url(d));
            let w = match first {
                Some(d) => {
                    myriad_measure::files::load_work(&myriad_measure::work::sidecar_for(d), None)?
                }
                None => Default::default(),
            };
            Some(
                crate::render::saved_path(&w, p)
                    .map_err(|e| anyhow::anyhow!("--play-path {p}: {e}"))?,
            )
        }
    };
    Ok(myriad_viewer::PathsAsked {
        views,
        save_as: a.record_path.clone(),
        play,
        play_recorded: recorded,
    })
}

/// `--volume` with `--volume-base` and `--volume-cell`, checked.
fn volume_asked(
    a: &ViewArgs,
    datasets: &[(String, Arc<Dataset>)],
) -> Result<Option<myriad_viewer::VolumeAsked>> {
    Ok(match &a.volume {
        None => None,
        Some(p) => {
            let pts = shape_arg(p, "--volume", Want::Polygon, datasets)?;
            myriad_measure::Polygon::new(&pts).map_err(anyhow::Error::msg)?;
            let base =
                match a.volume_base.as_str() {
                    "rim" => None,
                    b => Some(b.parse::<f64>().ok().filter(|z| z.is_finite()).ok_or_else(
                        || anyhow::anyhow!("--volume-base \"{b}\": rim or an elevation"),
                    )?),
                };
            if a.volume_cell.is_some_and(|c| !(c.is_finite() && c > 0.0)) {
                bail!("--volume-cell: a cell size must be positive");
            }
            Some(myriad_viewer::VolumeAsked {
                polygon: pts,
                base,
                cell: a.volume_cell,
            })
        }
    })
}

/// `--section` with `--section-width` (default: four times the first dataset's mean point
/// spacing), checked.
fn section_asked(
    a: &ViewArgs,
    datasets: &[(String, Arc<Dataset>)],
) -> Result<Option<(Vec<[f64; 2]>, f64)>> {
    Ok(match &a.section {
        None => None,
        Some(l) => {
            let line = shape_arg(l, "--section", Want::Line, datasets)?;
            let width = match a.section_width {
                Some(w) => w,
                None => {
                    let m = &datasets
                        .first()
                        .map(|d| d.1.meta.clone())
                        .ok_or_else(|| anyhow::anyhow!("no dataset"))?;
                    let s = m.bounds.size();
                    4.0 * (s[0] * s[1] / m.points.max(1) as f64).sqrt()
                }
            };
            myriad_measure::Corridor::new(&line, width).map_err(anyhow::Error::msg)?;
            Some((line, width))
        }
    })
}

/// Builds the scans of `to_build`, then watches every scan of `watched` while the viewer runs:
/// one whose files changed since its last build started is built again. Each dataset (or why
/// there is none) goes to `tx` with its layer; a build that failed is not tried again until the
/// scan changes once more. The first builds are drawn as they go (their snapshots in
/// `running`).
fn watch(
    to_build: Vec<(usize, Pending)>,
    mut watched: Watched,
    tx: std::sync::mpsc::Sender<myriad_viewer::Built>,
    running: myriad_viewer::builds::Running,
) {
    let opened = |d: Result<std::path::PathBuf>| {
        d.and_then(|d| Ok(Arc::new(Dataset::open(&d)?)))
            .map_err(|e| format!("{e:#}"))
    };
    for (i, pending) in to_build {
        let g = myriad_build::growing::Growing::new(myriad_build::growing::DEFAULT_EVERY);
        running.lock().expect("builds lock").insert(i, g.clone());
        let built = opened(crate::cached::build(&pending, Some(g)));
        running.lock().expect("builds lock").remove(&i);
        if tx.send((i, built)).is_err() {
            return;
        }
    }
    loop {
        std::thread::sleep(myriad_build::open::WATCH_EVERY);
        for (i, p) in watched.changed() {
            eprintln!(
                "{}: changed on disk: building its dataset again (what is shown stays until then)",
                p.display()
            );
            if tx
                .send((i, opened(crate::cached::dataset_for(&p))))
                .is_err()
            {
                return;
            }
        }
    }
}
