//! What a CRS's WKT (1 or 2) says of itself, for `info` and the viewers: its name, EPSG code,
//! kind, horizontal units and vertical part. Read from the text alone (no PROJ): the top-level
//! element's name and last authority, the horizontal and vertical elements of a compound CRS
//! found by matching brackets. The units are read here too, for measurements as well
//! ([`crate::measurement`] converts lengths with them): the metres per unit of a WKT's linear
//! `UNIT` ([`metres_per_unit`]) and the unit's name ([`unit_name`]).

/// A CRS as `info` names it.
#[derive(Debug, Clone, PartialEq)]
pub struct Described {
    pub name: Option<String>,
    pub epsg: Option<u32>,
    /// "projected", "geographic", "geocentric", "vertical", or "unknown".
    pub kind: &'static str,
    /// The horizontal coordinates' unit: "m", "ft", "US ft", "degrees" or "units".
    pub units: &'static str,
    /// A compound CRS's vertical part: its name, EPSG code and unit.
    pub vertical: Option<(Option<String>, Option<u32>, &'static str)>,
}

const PROJECTED: [&str; 3] = ["PROJCS", "PROJCRS", "PROJECTEDCRS"];
const GEOGRAPHIC: [&str; 3] = ["GEOGCS", "GEOGCRS", "GEOGRAPHICCRS"];
const GEOCENTRIC: [&str; 2] = ["GEOCCS", "GEODCRS"];
const VERTICAL: [&str; 3] = ["VERT_CS", "VERTCRS", "VERTICALCRS"];
const COMPOUND: [&str; 2] = ["COMPD_CS", "COMPOUNDCRS"];

/// The first element of `wkt` whose keyword is one of `keywords`, to its matching bracket.
fn element<'a>(wkt: &'a str, keywords: &[&str]) -> Option<&'a str> {
    let start = (keywords.iter())
        .filter_map(|k| {
            let mut from = 0;
            while let Some(i) = wkt[from..].find(&format!("{k}[")) {
                let at = from + i;
                // A whole keyword: not the tail of a longer one.
                let before = wkt[..at].chars().next_back();
                if before.is_none_or(|c| !c.is_ascii_alphanumeric() && c != '_') {
                    return Some(at);
                }
                from = at + 1;
            }
            None
        })
        .min()?;
    let mut depth = 0i32;
    let mut quoted = false;
    for (i, c) in wkt[start..].char_indices() {
        match c {
            '"' => quoted = !quoted,
            '[' | '(' if !quoted => depth += 1,
            ']' | ')' if !quoted => {
                depth -= 1;
                if depth == 0 {
                    return Some(&wkt[start..start + i + 1]);
                }
            }
            _ => {}
        }
    }
    None
}

/// The EPSG code of element `e` itself (its own `AUTHORITY` or `ID`, not a part's: a unit's or
/// a datum's code says nothing of the CRS), or of `EPSG:N`.
pub fn own_epsg(e: &str) -> Option<u32> {
    let t = e.trim();
    if let Some(n) = t.strip_prefix("EPSG:") {
        // `EPSG:H+V` (a compound of two codes): the horizontal one.
        return n.split('+').next()?.trim().parse().ok();
    }
    let (mut depth, mut quoted, mut found) = (0i32, false, None);
    for (i, c) in t.char_indices() {
        match c {
            '"' => quoted = !quoted,
            '[' | '(' if !quoted => depth += 1,
            ']' | ')' if !quoted => depth -= 1,
            _ if !quoted && depth == 1 => {
                let rest = &t[i..];
                let after = ["AUTHORITY[\"EPSG\",", "ID[\"EPSG\","]
                    .iter()
                    .find_map(|k| rest.strip_prefix(k));
                let prior = t[..i].chars().next_back();
                if let Some(a) = after
                    && prior.is_some_and(|p| p == ',' || p == '[' || p.is_whitespace())
                {
                    let n: String = a
                        .trim_start_matches('"')
                        .chars()
                        .take_while(|c| c.is_ascii_digit())
                        .collect();
                    found = n.parse().ok().or(found);
                }
            }
            _ => {}
        }
    }
    found
}

fn name_of(e: &str) -> Option<String> {
    let inner = &e[e.find('[')? + 1..];
    let inner = inner.trim_start().strip_prefix('"')?;
    Some(inner[..inner.find('"')?].to_string())
}

fn keyword(e: &str) -> &str {
    e.trim_start().split('[').next().unwrap_or("").trim()
}

/// What `crs` (WKT, or `EPSG:N`) says of itself.
pub fn describe(crs: &str) -> Described {
    let t = crs.trim();
    if let Some(n) = t.strip_prefix("EPSG:") {
        let mut codes = n.split('+').map(|c| c.trim().parse::<u32>().ok());
        // A bare code (GeoTIFF keys) says what it is through PROJ's database, where PROJ is here.
        #[cfg(not(target_arch = "wasm32"))]
        if let Ok(wkt) = myriad_io::proj::Crs::new(t).and_then(|c| c.wkt())
            && !wkt.trim_start().starts_with("EPSG:")
        {
            let mut d = describe(&wkt);
            d.epsg = d.epsg.or(codes.next().flatten());
            if let Some(v) = &mut d.vertical {
                v.1 = v.1.or(codes.next().flatten());
            }
            return d;
        }
        return Described {
            name: None,
            epsg: codes.next().flatten(),
            kind: "unknown",
            units: "units",
            vertical: codes.next().map(|v| (None, v, "units")),
        };
    }
    let top = keyword(t);
    let horizontal = if COMPOUND.contains(&top) {
        element(
            t,
            &[PROJECTED.as_slice(), &GEOGRAPHIC, &GEOCENTRIC].concat(),
        )
    } else {
        Some(t)
    };
    let h_kw = horizontal.map(keyword).unwrap_or("");
    let kind = if PROJECTED.contains(&h_kw) {
        "projected"
    } else if GEOGRAPHIC.contains(&h_kw) {
        "geographic"
    } else if GEOCENTRIC.contains(&h_kw) {
        "geocentric"
    } else if VERTICAL.contains(&h_kw) {
        "vertical"
    } else {
        "unknown"
    };
    let units = match (kind, horizontal) {
        ("geographic", _) => "degrees",
        (_, Some(h)) => {
            // A projected CRS's own unit: its last linear one outside its vertical part.
            unit_name(metres_per_unit(h))
        }
        _ => "units",
    };
    let vertical = if VERTICAL.contains(&h_kw) {
        None
    } else {
        element(t, &VERTICAL).map(|v| (name_of(v), own_epsg(v), unit_name(metres_per_unit(v))))
    };
    Described {
        name: name_of(t),
        epsg: own_epsg(t),
        kind,
        units,
        vertical,
    }
}

impl Described {
    /// One line: `NAME (EPSG:N), KIND, units U[; vertical NAME (EPSG:M), U]`.
    pub fn line(&self) -> String {
        let code = |c: Option<u32>| c.map(|c| format!(" (EPSG:{c})")).unwrap_or_default();
        let mut s = format!(
            "{}{}, {}, units {}",
            self.name.as_deref().unwrap_or("unnamed"),
            code(self.epsg),
            self.kind,
            self.units
        );
        if let Some((n, c, u)) = &self.vertical {
            s.push_str(&format!(
                "; vertical {}{}, {u}",
                n.as_deref().unwrap_or("unnamed"),
                code(*c)
            ));
        }
        s
    }
}

/// Metres per unit of a CRS's horizontal coordinates, from its WKT: the factor of its last
/// linear `UNIT` (`None` for a geographic CRS, a bare `EPSG:n`, or none).
pub fn metres_per_unit(wkt: &str) -> Option<f64> {
    let mut found = None;
    for part in wkt.split("UNIT[").skip(1) {
        let name = part.split('"').nth(1)?.to_ascii_lowercase();
        let factor: f64 = part
            .split(',')
            .nth(1)?
            .trim_end_matches(']')
            .trim()
            .parse()
            .ok()?;
        let linear = ["metre", "meter", "foot", "feet", "ft"]
            .iter()
            .any(|u| name.contains(u));
        if linear && factor > 0.0 {
            found = Some(factor);
        }
    }
    // A geographic CRS (degrees horizontally) has no length per coordinate unit.
    if wkt.trim_start().starts_with("GEOGCS") || wkt.trim_start().starts_with("GEOGCRS") {
        return None;
    }
    found
}

/// The name of a length unit of `metres` (from [`metres_per_unit`]): "m", "ft", "US ft", or
/// "units" where the CRS does not say.
pub fn unit_name(metres: Option<f64>) -> &'static str {
    match metres {
        Some(m) if (m - 1.0).abs() < 1e-9 => "m",
        Some(m) if (m - 0.3048).abs() < 1e-9 => "ft",
        Some(m) if (m - 1200.0 / 3937.0).abs() < 1e-9 => "US ft",
        _ => "units",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const UTM: &str = r#"PROJCS["WGS 84 / UTM zone 33N",GEOGCS["WGS 84",DATUM["WGS_1984",SPHEROID["WGS 84",6378137,298.257223563,AUTHORITY["EPSG","7030"]],AUTHORITY["EPSG","6326"]],PRIMEM["Greenwich",0],UNIT["degree",0.0174532925199433],AUTHORITY["EPSG","4326"]],PROJECTION["Transverse_Mercator"],UNIT["metre",1,AUTHORITY["EPSG","9001"]],AUTHORITY["EPSG","32633"]]"#;

    #[test]
    fn names_codes_units_and_vertical_parts() {
        let d = describe(UTM);
        assert_eq!(d.name.as_deref(), Some("WGS 84 / UTM zone 33N"));
        assert_eq!((d.epsg, d.kind, d.units), (Some(32633), "projected", "m"));
        assert_eq!(d.vertical, None);
        assert_eq!(
            d.line(),
            "WGS 84 / UTM zone 33N (EPSG:32633), projected, units m"
        );
        let feet = r#"PROJCS["NAD83(HARN) / Oregon GIC Lambert (ft)",GEOGCS["NAD83(HARN)",UNIT["degree",0.0174532925199433]],PROJECTION["Lambert_Conformal_Conic_2SP"],UNIT["foot",0.3048,AUTHORITY["EPSG","9002"]],AUTHORITY["EPSG","2994"]]"#;
        let d = describe(feet);
        assert_eq!((d.epsg, d.units), (Some(2994), "ft"));
        // No code of its own: none (not its unit's 9002).
        let d = describe(&feet.replace(r#",AUTHORITY["EPSG","2994"]"#, ""));
        assert_eq!((d.epsg, d.units), (None, "ft"));
        let compound = format!(
            r#"COMPD_CS["ETRS89 / UTM 32N + DHHN2016 height",{},VERT_CS["DHHN2016 height",VERT_DATUM["Deutsches Haupthoehennetz 2016",2005],UNIT["metre",1],AXIS["Up",UP],AUTHORITY["EPSG","7837"]],AUTHORITY["EPSG","0"]]"#,
            UTM.replace("32633", "25832")
        );
        let d = describe(&compound);
        assert_eq!(
            d.name.as_deref(),
            Some("ETRS89 / UTM 32N + DHHN2016 height")
        );
        assert_eq!((d.kind, d.units), ("projected", "m"));
        assert_eq!(
            d.vertical,
            Some((Some("DHHN2016 height".into()), Some(7837), "m"))
        );
        let geo = r#"GEOGCRS["WGS 84",DATUM["World Geodetic System 1984",ELLIPSOID["WGS 84",6378137,298.257223563]],CS[ellipsoidal,2],ANGLEUNIT["degree",0.0174532925199433],ID["EPSG",4326]]"#;
        let d = describe(geo);
        assert_eq!(
            (d.epsg, d.kind, d.units),
            (Some(4326), "geographic", "degrees")
        );
        let bare = describe("EPSG:2056");
        let both = describe("EPSG:2903+5103");
        if myriad_io::proj::available() {
            // Named from PROJ's database.
            assert_eq!(
                (bare.epsg, bare.kind, bare.units),
                (Some(2056), "projected", "m")
            );
            assert_eq!(bare.name.as_deref(), Some("CH1903+ / LV95"));
            // (EPSG:5103 is NAVD88's datum, no CRS: PROJ refuses it, and the codes stay.)
            assert_eq!((both.epsg, both.kind), (Some(2903), "unknown"));
            let both = describe("EPSG:2903+6360");
            assert_eq!(
                (both.kind, both.units),
                ("projected", "US ft"),
                "{}",
                both.line()
            );
            let v = both.vertical.clone().unwrap();
            assert_eq!(
                (v.0.as_deref(), v.1),
                (Some("NAVD88 height (ftUS)"), Some(6360))
            );
        } else {
            assert_eq!((bare.epsg, bare.name), (Some(2056), None));
            assert_eq!(
                (both.epsg, both.vertical.clone()),
                (Some(2903), Some((None, Some(5103), "units")))
            );
            assert_eq!(
                both.line(),
                "unnamed (EPSG:2903), unknown, units units; vertical unnamed (EPSG:5103), units"
            );
        }
        assert_eq!(describe("not a crs").kind, "unknown");
    }

    #[test]
    fn units_from_wkt() {
        let utm = r#"PROJCS["WGS 84 / UTM zone 33N",GEOGCS["WGS 84",UNIT["degree",0.0174532925199433]],UNIT["metre",1,AUTHORITY["EPSG","9001"]]]"#;
        assert_eq!(metres_per_unit(utm), Some(1.0));
        let ft = r#"PROJCS["NAD83 / Oregon GIC Lambert (ft)",GEOGCS["NAD83",UNIT["degree",0.01745]],UNIT["foot",0.3048,AUTHORITY["EPSG","9002"]]]"#;
        assert_eq!(metres_per_unit(ft), Some(0.3048));
        assert_eq!(
            metres_per_unit(r#"GEOGCS["WGS 84",UNIT["degree",0.0174532925199433]]"#),
            None
        );
        assert_eq!(metres_per_unit("EPSG:32633"), None);
    }
}
