//! What the viewer writes out: screenshots, the text of a picked point, and the shortcuts the
//! help window lists.

use eframe::egui;

pub(crate) fn write_png(path: &std::path::Path, image: &egui::ColorImage) -> Result<(), String> {
    let [w, h] = image.size;
    let rgba: Vec<u8> = image.pixels.iter().flat_map(|c| c.to_array()).collect();
    let write = || -> Result<(), Box<dyn std::error::Error>> {
        let file = myriad_io::atomic::AtomicFile::create(path, true)?;
        {
            let f = file.open_write()?;
            let mut enc = png::Encoder::new(std::io::BufWriter::new(f), w as u32, h as u32);
            enc.set_color(png::ColorType::Rgba);
            enc.set_depth(png::BitDepth::Eight);
            let mut writer = enc.write_header()?;
            writer.write_image_data(&rgba)?;
            writer.finish()?;
        }
        file.commit()?;
        Ok(())
    };
    write().map_err(|e| e.to_string())
}

/// A picked point as lines of text: coordinates and every attribute.
pub(crate) fn describe(p: &myriad_render::Picked) -> String {
    let b = &p.batch;
    let i = p.index;
    let mut s = format!(
        "x {:.3}\ny {:.3}\nz {:.3}\nnode {}",
        p.position[0], p.position[1], p.position[2], p.node
    );
    if let Some(v) = &b.intensity {
        s += &format!("\nintensity {}", v[i]);
    }
    if let Some(v) = &b.classification {
        s += &format!("\nclass {}", v[i]);
    }
    if let Some(v) = &b.return_number {
        s += &format!("\nreturn {}", v[i]);
    }
    if let Some(v) = &b.point_source_id {
        s += &format!("\nsource {}", v[i]);
    }
    if let Some(v) = &b.gps_time {
        s += &format!("\ngps time {:.6}", v[i]);
    }
    if let Some(v) = &b.rgb {
        s += &format!("\nrgb {} {} {}", v[i][0], v[i][1], v[i][2]);
    }
    s
}

/// A picked point's longitude, latitude and ellipsoidal height as lines to add (none where
/// they are not known).
pub(crate) fn geographic(lon_lat_h: Option<[f64; 3]>) -> String {
    match lon_lat_h {
        Some([lon, lat, h]) => {
            format!("\nlon {lon:.8}°\nlat {lat:.8}°\nh {h:.3} m (WGS 84 ellipsoid)")
        }
        None => String::new(),
    }
}

/// The shortcuts the help window lists.
pub(crate) const HELP: &[(&str, &str)] = &[
    ("left drag", "orbit around the point under the cursor"),
    ("right or middle drag", "pan"),
    ("wheel", "zoom towards the cursor (fly mode: speed)"),
    ("double click", "pick a point: coordinates and attributes"),
    (
        "M / N / A",
        "measure distance / height / area: click points, right click ends",
    ),
    (
        "O / C / Z / I",
        "measure an angle (3 points) / a circle (3) / an azimuth (2) / a point",
    ),
    (
        "T",
        "annotate: click a point, then give it a title and text in the panel",
    ),
    (
        "X",
        "profile: click points of a section line, right click cuts (width in the panel)",
    ),
    (
        "V",
        "volume: click a polygon's corners, right click measures (base and cell in the panel)",
    ),
    ("Esc", "stop measuring, annotating, drawing"),
    (
        "G",
        "fly mode on/off: W A S D to move, Q E down/up, drag to look",
    ),
    ("F", "frame all"),
    (
        "1 / 2 / 3 / 4 / 5 / 6",
        "top / front / right / bottom / back / left view",
    ),
    ("0", "parallel (orthographic) view on/off"),
    ("P", "screenshot (myriad-screenshot-N.png)"),
    ("H", "this help"),
];

#[cfg(test)]
mod geographic_tests {
    #[test]
    fn longitude_latitude_and_height_lines() {
        assert_eq!(super::geographic(None), "");
        assert_eq!(
            super::geographic(Some([-123.071212345, 44.05156, 120.5])),
            "\nlon -123.07121235°\nlat 44.05156000°\nh 120.500 m (WGS 84 ellipsoid)"
        );
        if myriad_io::proj::available() {
            let mut g = myriad_io::proj::Geographic::new("EPSG:32610").unwrap();
            let p = g.of([500_000.0, 4_877_429.0, 100.0]).unwrap();
            assert!((p[0] + 123.0).abs() < 1e-9 && (p[1] - 44.05).abs() < 0.01 && p[2] == 100.0);
        }
    }
}
