//! `myriad bench ...`: the benchmarks' command line; each is a module of `myriad-bench`.

use anyhow::Result;
use clap::Subcommand;

#[derive(Subcommand)]
pub enum BenchCommand {
    /// Reading speed of files; for LAS/LAZ also the raw speed of the las/laz crates (baseline)
    Read(myriad_bench::read::ReadArgs),
    /// Speed and peak memory of `synth`
    Synth(myriad_bench::synth::SynthBenchArgs),
    /// Conversion speed, peak memory and size (each run a separate `myriad convert` process),
    /// next to the raw LAS/LAZ decode of the same file
    Convert(myriad_bench::convert::ConvertBenchArgs),
    /// Image quality of the level of detail at a point budget (PSNR against every point, next
    /// to as many random points, and blocks: points drawn 6 pixels wide or more where the image
    /// of every point has none) in three standard views, and the frame time of the pipeline
    Render(myriad_bench::render::RenderBenchArgs),
    /// The cost of each post pass (fill, shade, ssao, edl, blur, aa) at 1280x720 and
    /// 2160x2160, and the PSNR of no pass, fill, fill+blur and the default chain at 250 k and
    /// 1 M points against every point
    Passes(myriad_bench::passes::PassesBenchArgs),
    /// One file converted with every structure (octree, layered, kd): build speed, peak memory,
    /// bytes per point, nodes, depth, PSNR at a budget in three views, frame time
    Structures(myriad_bench::structures::StructuresBenchArgs),
    /// Scheiblauer 2006's tables 6.1-6.4: every point, one sequential point tree (SPT), one MOSPT
    /// and the nested octree (culling off and on) from a distance, the border and the centre:
    /// points in memory, processed and drawn, selection and frame time
    Baselines(myriad_bench::baselines::BaselinesBenchArgs),
    /// Occlusion culling from a view inside and one outside each dataset: nodes and points
    /// selected, nodes culled, selection and frame time, PSNR against every point unculled
    Culling(myriad_bench::culling::CullingBenchArgs),
    /// Table 3 of Kanzok et al. 2015: a scan converted at several node capacities, each walked
    /// through an overview, a close and a detail view with occlusion culling and without: nodes,
    /// points, frame time and the time to load each view
    Capacity(myriad_bench::capacity::CapacityBenchArgs),
    /// The ground `myriad ground` finds against labelled scans: type I, type II and total
    /// error, time and peak memory
    Ground(myriad_bench::ground::GroundBenchArgs),
    /// Layered datasets' contours (the subtree's oriented box, as stored) against the contours
    /// of each node's own points (Kanzok et al. 2015): their areas and thicknesses, per level
    Contours(myriad_bench::contours::ContoursBenchArgs),
    /// Surfaces from a view's points: cells and the milliseconds of cluster, move,
    /// reduce, reconstruct and the frame for the full method, without move and for an octree
    /// level as the baseline; distance from the points to the surface; holes
    Surface(myriad_bench::surface::SurfaceBenchArgs),
    /// Stereo frames: mono, both eyes in two passes and in one, with and without the
    /// hidden-area mask, at 2160x2160 per eye
    Stereo(myriad_bench::stereo::StereoBenchArgs),
    /// Export speed and peak memory (COPC, Potree) next to PotreeConverter 2 converting the
    /// dataset's input in the same run
    Export(myriad_bench::export::ExportBenchArgs),
    /// Opening: time to the first image and to convergence (cold and warm page cache), pages
    /// read and hierarchy memory, next to reading every hierarchy page
    Open(myriad_bench::open::OpenBenchArgs),
    /// A raw scan (LAS/LAZ file or folder of tiles) before any dataset of it: time to the first
    /// image cold and bytes read, `convert` alone and the finished dataset's image, the PSNR of
    /// what shows 1, 2, 5, 10 and 30 s in
    OpenScan(myriad_bench::open_scan::OpenScanBenchArgs),
    /// `myriad serve` under concurrent random range reads, next to nginx in the same run:
    /// requests/s, MB/s, latency, errors, server memory
    Serve(myriad_bench::serve::ServeBenchArgs),
    /// Prefetching off and on while orbiting: frames with nodes missing, time to settle
    Prefetch(myriad_bench::prefetch::PrefetchBenchArgs),
    /// Time to the first image and to convergence in the browser: Myriad's web viewer next to
    /// Potree 1.8 on PotreeConverter's output, from the same server, in headless Chromium
    Web(myriad_bench::web::WebBenchArgs),
    /// A cross-section, cold and warm: time, points, nodes read, next to extracting its box
    Profile(myriad_bench::profile::ProfileBenchArgs),
    /// A volume over a polygon, cold and warm: time, points, nodes read, next to extracting
    /// its box
    Volume(myriad_bench::volume::VolumeBenchArgs),
    /// A build on one machine next to the same build as N parts and a merge on Slurm (the
    /// cluster SLURM_CONF names), same cores: wall time, each part's time and peak memory, merge
    Partition(myriad_bench::partition::PartitionBenchArgs),
}

pub fn run(c: BenchCommand) -> Result<()> {
    match c {
        BenchCommand::Read(a) => myriad_bench::read::run(a),
        BenchCommand::Synth(a) => myriad_bench::synth::run(a),
        BenchCommand::Convert(a) => myriad_bench::convert::run(a),
        BenchCommand::Render(a) => myriad_bench::render::run(a),
        BenchCommand::Structures(a) => myriad_bench::structures::run(a),
        BenchCommand::Baselines(a) => myriad_bench::baselines::run(a),
        BenchCommand::Passes(a) => myriad_bench::passes::run(a),
        BenchCommand::Culling(a) => myriad_bench::culling::run(a),
        BenchCommand::Capacity(a) => myriad_bench::capacity::run(a),
        BenchCommand::Contours(a) => myriad_bench::contours::run(a),
        BenchCommand::Ground(a) => myriad_bench::ground::run(a),
        BenchCommand::Surface(a) => myriad_bench::surface::run(a),
        BenchCommand::Stereo(a) => myriad_bench::stereo::run(a),
        BenchCommand::Export(a) => myriad_bench::export::run(a),
        BenchCommand::Open(a) => myriad_bench::open::run(a),
        BenchCommand::OpenScan(a) => myriad_bench::open_scan::run(a),
        BenchCommand::Serve(a) => myriad_bench::serve::run(a),
        BenchCommand::Prefetch(a) => myriad_bench::prefetch::run(a),
        BenchCommand::Web(a) => myriad_bench::web::run(a),
        BenchCommand::Profile(a) => myriad_bench::profile::run(a),
        BenchCommand::Volume(a) => myriad_bench::volume::run(a),
        BenchCommand::Partition(a) => myriad_bench::partition::run_bench(a),
    }
}
