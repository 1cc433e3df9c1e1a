//! GeoJSON (RFC 7946) of the tools' results, for GIS programs (QGIS, ArcGIS, shapely): the
//! coordinates are the dataset's own, and the CRS is named in the legacy `crs` member
//! (`urn:ogc:def:crs:EPSG::N`, from the WKT's own EPSG authority) that GDAL and QGIS read, since
//! RFC 7946 itself allows only WGS 84.

use serde_json::{Value, json};

/// The EPSG code of a CRS: the outermost object's own `AUTHORITY["EPSG","N"]` (WKT 1) or
/// `ID["EPSG",N]` (WKT 2), never a unit's or a datum's; or an `EPSG:N` text
/// ([`crate::crs::own_epsg`]).
pub fn epsg_code(crs: &str) -> Option<u32> {
    crate::crs::own_epsg(crs)
}

/// A feature collection of `features`, with the CRS named where it has an EPSG code.
pub fn collection(features: Vec<Value>, crs: Option<&str>) -> Value {
    let mut c = json!({ "type": "FeatureCollection", "features": features });
    if let Some(code) = crs.and_then(epsg_code) {
        c["crs"] = json!({
            "type": "name",
            "properties": { "name": format!("urn:ogc:def:crs:EPSG::{code}") }
        });
    }
    c
}

/// A feature of a geometry and properties.
pub fn feature(geometry: Value, properties: Value) -> Value {
    json!({ "type": "Feature", "geometry": geometry, "properties": properties })
}

/// A polygon's geometry (closed, as GeoJSON wants), at elevation `z` where given.
pub fn polygon_geometry(pts: &[[f64; 2]], z: Option<f64>) -> Value {
    let mut ring: Vec<Value> = pts
        .iter()
        .map(|p| match z {
            Some(z) => json!([p[0], p[1], z]),
            None => json!([p[0], p[1]]),
        })
        .collect();
    ring.push(ring[0].clone());
    json!({ "type": "Polygon", "coordinates": [ring] })
}

/// A line's geometry.
pub fn line_geometry(pts: &[[f64; 2]]) -> Value {
    json!({ "type": "LineString", "coordinates": pts.iter().map(|p| json!([p[0], p[1]])).collect::<Vec<_>>() })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn epsg_codes() {
        let utm = r#"PROJCS["WGS 84 / UTM zone 33N",GEOGCS["WGS 84",AUTHORITY["EPSG","4326"]],UNIT["metre",1,AUTHORITY["EPSG","9001"]],AUTHORITY["EPSG","32633"]]"#;
        assert_eq!(epsg_code(utm), Some(32633));
        assert_eq!(epsg_code("EPSG:2992"), Some(2992));
        assert_eq!(epsg_code(r#"PROJCRS["x",ID["EPSG",6557]]"#), Some(6557));
        assert_eq!(epsg_code(r#"LOCAL_CS["site"]"#), None);
        // A unit's code is not the CRS's.
        let no_code = r#"PROJCS["Lambert (ft)",UNIT["foot",0.3048,AUTHORITY["EPSG","9002"]]]"#;
        assert_eq!(epsg_code(no_code), None);
        let c = collection(vec![], Some(utm));
        assert_eq!(
            c["crs"]["properties"]["name"],
            "urn:ogc:def:crs:EPSG::32633"
        );
        let p = polygon_geometry(&[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]], None);
        assert_eq!(p["coordinates"][0].as_array().unwrap().len(), 4, "closed");
    }
}
