//! Tests on the real scans in ../shared/data. Each test skips, saying so, when the folder is
//! missing (a user's fresh clone); CI has it.

use myriad_core::{Aabb, PointBatch};
use myriad_io::las::{LasSink, LasSource, LasWriteOptions};
use myriad_io::{OpenOptions, PointSource, open, scan};
use std::path::{Path, PathBuf};

fn data_dir() -> Option<PathBuf> {
    let d = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data");
    if d.is_dir() {
        Some(d)
    } else {
        // Written to the stderr handle, not with eprintln!, which the test harness captures:
        // a skipped test must say so.
        use std::io::Write;
        let _ = writeln!(
            std::io::stderr(),
            "SKIPPED: {} not found; real-data tests need ../shared/data",
            d.display()
        );
        None
    }
}

/// Point counts from ../shared/data/README.md; the ranged rows of its small-scans table were
/// checked one by one with laspy 2.7 (`laspy.open(f).header.point_count`).
const COUNTS: &[(&str, u64)] = &[
    ("KY_RiverLockDam4_KyFromAbove_merged.laz", 7_185_262),
    ("sheridan_potree_merged.laz", 6_050_469),
    (
        "NRW_3dm_32_291_5744_1_nw_potreeLOD0-4_merged.laz",
        3_570_117,
    ),
    ("potree_test_converted_L001_merged.laz", 1_460_879),
    ("PDAL__las_autzen_trim.las", 110_000),
    ("PDAL__laz_autzen_trim.laz", 110_000),
    ("PDAL__las_autzen_trim_7.las", 110_000),
    ("PDAL__laz_las_with_several_extra_byte_bloc.laz", 697_721),
    ("PDAL__copc_lone-star.copc.laz", 518_862),
    ("PDAL__ept_source_lone-star.laz", 518_862),
    ("potree__lion_takanawa.copc.laz", 341_989),
    ("loadersgl__indoor.laz", 808_042),
    ("PDAL__filters_hexbin-crop.las", 38_367),
    ("PDAL__las_4_6_crop.las", 23_875),
    ("PDAL__las_sample_c.las", 14_408),
    ("PDAL__las_test1_4.las", 1_000),
    ("PDAL__las_1.2-with-color.las", 1_065),
    ("laspy__fullwave.laz", 10_750),
    ("laspy__vegetation_1_3.las", 10_683),
    ("laspy__append-bug.laz", 37_805),
    ("untwine__eb.laz", 9_310),
    ("lasrs__32-1-472-150-76.laz", 5_658),
    ("lidR__Megaplot.laz", 81_590),
    ("lidR__Topography.laz", 73_403),
    ("pye57__pumpAVisualReferenceImage.e57", 155_201),
    ("e57rs__bunnyFloat.e57", 30_571),
    ("Minisal_ICP__bun000.ply", 40_256),
    ("loadersgl__bunny.ply", 34_834),
    ("loadersgl__bun_zipper.ply", 35_947),
    ("PCLdata__terrain_CSite1_red1-utm.pcd", 522_674),
    ("PCLdata__tutorials_room_scan1.pcd", 112_586),
    ("PDAL__pcd_autzen-utm.pcd", 1_065),
];

#[test]
fn every_file_holds_the_documented_point_count() {
    let Some(dir) = data_dir() else { return };
    for (name, expected) in COUNTS {
        let path = dir.join(name);
        let mut src = open(&path, &OpenOptions::default()).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(src.info().points, Some(*expected), "{name}: header count");
        let (n, _) = scan(src.as_mut()).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(
            n + src.skipped_non_finite(),
            *expected,
            "{name}: streamed count"
        );
        assert_eq!(src.skipped_non_finite(), 0, "{name}: unexpected NaN points");
    }
    let listed = std::fs::read_dir(&dir).unwrap().filter(|e| {
        let n = e.as_ref().unwrap().file_name().into_string().unwrap();
        !n.ends_with(".md") && n != "SHA256SUMS"
    });
    assert_eq!(
        listed.count(),
        COUNTS.len(),
        "a file in shared/data has no expected count here"
    );
}

/// Bounds of the points (not the header), as laspy 2.7 computes them (`l.x.min()` ...).
#[test]
fn bounds_match_an_independent_reading() {
    let Some(dir) = data_dir() else { return };
    let check = |name: &str, min: [f64; 3], max: [f64; 3]| {
        let mut src = open(&dir.join(name), &OpenOptions::default()).unwrap();
        let (_, b) = scan(src.as_mut()).unwrap();
        for a in 0..3 {
            assert!(
                (b.min[a] - min[a]).abs() < 1e-6,
                "{name} min[{a}] {} vs {}",
                b.min[a],
                min[a]
            );
            assert!(
                (b.max[a] - max[a]).abs() < 1e-6,
                "{name} max[{a}] {} vs {}",
                b.max[a],
                max[a]
            );
        }
    };
    check(
        "KY_RiverLockDam4_KyFromAbove_merged.laz",
        [5170845.29, 3964547.02, 452.07],
        [5175845.28, 3969547.01, 788.18],
    );
    check(
        "sheridan_potree_merged.laz",
        [-11.416, -10.41, -0.295],
        [20.295, 1.318, 26.817],
    );
    check(
        "PDAL__las_autzen_trim.las",
        [636001.76, 848935.20, 406.26],
        [637179.22, 849497.9, 520.51],
    );
    check(
        "PDAL__laz_las_with_several_extra_byte_bloc.laz",
        [484649.36, 6632629.73, 99.65],
        [484999.99, 6632999.99, 120.42],
    );
    check(
        "laspy__fullwave.laz",
        [194267.419, 8249096.014, 989.944],
        [194318.295, 8249137.34, 1003.704],
    );
    // The header of this COPC file states -4.985 where its points reach -4.99.
    check(
        "potree__lion_takanawa.copc.laz",
        [-4.99, 1.04, -3.45],
        [-0.79, 6.72, 1.12],
    );
}

fn read_all(path: &Path) -> PointBatch {
    let mut src = LasSource::open(path).unwrap_or_else(|e| panic!("{e}"));
    let mut all: Option<PointBatch> = None;
    while let Some(b) = src.read_batch(1 << 20).unwrap() {
        match &mut all {
            Some(a) => a.append(&b),
            None => all = Some(b),
        }
    }
    all.unwrap_or_default()
}

/// Compares two batches column by column and names the first difference.
fn assert_same(name: &str, a: &PointBatch, b: &PointBatch) {
    assert_eq!(a.len(), b.len(), "{name}: point count");
    macro_rules! col {
        ($f:ident) => {
            assert_eq!(
                a.$f.is_some(),
                b.$f.is_some(),
                "{name}: column {} presence",
                stringify!($f)
            );
            if let (Some(x), Some(y)) = (&a.$f, &b.$f) {
                if let Some(i) = x
                    .iter()
                    .zip(y)
                    .position(|(p, q)| format!("{p:?}") != format!("{q:?}"))
                {
                    panic!(
                        "{name}: column {} differs at point {i}: {:?} vs {:?}",
                        stringify!($f),
                        x[i],
                        y[i]
                    );
                }
            }
        };
    }
    assert!(a.positions == b.positions, "{name}: positions differ");
    col!(intensity);
    col!(return_number);
    col!(number_of_returns);
    col!(classification);
    col!(classification_flags);
    col!(scan_flags);
    col!(scanner_channel);
    col!(scan_angle);
    col!(user_data);
    col!(point_source_id);
    col!(gps_time);
    col!(rgb);
    col!(nir);
    col!(wave_packet);
    col!(extra_bytes);
}

fn round_trip(name: &str, dir: &Path, out: &Path) {
    let input = dir.join(name);
    let src = LasSource::open(&input).unwrap();
    let header = src.header().clone();
    let original = read_all(&input);
    let ext = if name.ends_with(".laz") { "laz" } else { "las" };
    let target = out.join(format!("rt.{ext}"));
    let mut sink = LasSink::create(&target, LasWriteOptions::like(&header), true).unwrap();
    for start in (0..original.len()).step_by(1 << 20) {
        sink.write(&original.slice(start..original.len().min(start + (1 << 20))))
            .unwrap();
    }
    assert_eq!(sink.finish().unwrap(), original.len() as u64);
    let back_src = LasSource::open(&target).unwrap();
    let (a, b) = (src.info(), back_src.info());
    assert_eq!(
        a.version.replace(" (COPC)", ""),
        b.version,
        "{name}: version and point format"
    );
    assert_eq!(
        (a.scale, a.offset),
        (b.scale, b.offset),
        "{name}: scale and offset"
    );
    assert_eq!(
        a.schema, b.schema,
        "{name}: schema (extra-bytes dimensions included)"
    );
    assert_eq!(a.crs, b.crs, "{name}: CRS");
    assert_same(name, &original, &read_all(&target));
}

#[test]
fn las_and_laz_round_trips_keep_every_field() {
    let Some(dir) = data_dir() else { return };
    let out = std::env::temp_dir().join(format!("myriad-rt-{}", std::process::id()));
    std::fs::create_dir_all(&out).unwrap();
    for (name, _) in COUNTS
        .iter()
        .filter(|(n, _)| n.ends_with(".las") || n.ends_with(".laz"))
    {
        round_trip(name, &dir, &out);
    }
    std::fs::remove_dir_all(&out).unwrap();
}

#[test]
fn e57_pose_intensity_and_colour() {
    let Some(dir) = data_dir() else { return };
    let mut src = open(
        &dir.join("pye57__pumpAVisualReferenceImage.e57"),
        &OpenOptions::default(),
    )
    .unwrap();
    let b = src.read_batch(usize::MAX).unwrap().unwrap();
    let rgb = b.rgb.as_ref().expect("pump scan has colour");
    let intensity = b.intensity.as_ref().expect("pump scan has intensity");
    assert!(
        rgb.iter().any(|c| c[0] != c[1]),
        "colour channels are all grey"
    );
    assert!(intensity.iter().any(|&i| i > 1000) && intensity.iter().any(|&i| i < 60000));
    let mut bb = Aabb::EMPTY;
    b.positions.iter().for_each(|p| bb.extend(*p));
    // The scan's pose puts the pump within a few metres of the origin.
    assert!(bb.size().iter().all(|s| *s > 1.0 && *s < 10.0), "{bb:?}");
}
