//! GeoJSON floor plans (`geojson_map.json`) in longitude/latitude degrees, brought into the
//! metre frame of the waypoints, and written back.
//!
//! The transform: the bounding box of the first feature (the floor outline) is mapped
//! linearly onto `[0, width] x [0, height]`, longitude to `x`, latitude to `y`. The other
//! features are units (shops, rooms) with a `name` property. Sizes are bounded by
//! [`Limits::max_json_bytes`], [`Limits::max_geojson_features`] and
//! [`Limits::max_geojson_vertices`].

use crate::{IoError, Limits};
use serde::{Deserialize, Serialize};
use serde_json::{Value, json};
use std::io::{Read, Write};
use std::path::Path;
use wipdr_core::{FloorPlan, Point2, Polygon, Unit};

/// A longitude/latitude rectangle, degrees.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LonLatBox {
    /// West edge (smallest longitude).
    pub min_lon: f64,
    /// South edge (smallest latitude).
    pub min_lat: f64,
    /// East edge (largest longitude).
    pub max_lon: f64,
    /// North edge (largest latitude).
    pub max_lat: f64,
}

impl LonLatBox {
    /// A box with its south-west corner at (`lon`, `lat`) spanning roughly `width` x `height`
    /// metres (equirectangular approximation, 111 320 m per degree of latitude). Handy for
    /// synthetic floors; the reader only uses the box's corners.
    pub fn around(lon: f64, lat: f64, width: f64, height: f64) -> Self {
        const M_PER_DEG: f64 = 111_320.0;
        let cos_lat = lat.to_radians().cos().abs().max(1e-6);
        Self {
            min_lon: lon,
            min_lat: lat,
            max_lon: lon + width / (M_PER_DEG * cos_lat),
            max_lat: lat + height / M_PER_DEG,
        }
    }

    fn is_valid(&self) -> bool {
        [self.min_lon, self.min_lat, self.max_lon, self.max_lat]
            .iter()
            .all(|v| v.is_finite())
            && self.max_lon > self.min_lon
            && self.max_lat > self.min_lat
    }
}

/// A floor plan read from GeoJSON.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlanRead {
    /// The plan in metres.
    pub plan: FloorPlan,
    /// The bounding box of the first feature, degrees (the transform's source rectangle).
    pub lonlat_box: LonLatBox,
    /// Features that were not polygons or were degenerate, skipped (and logged).
    pub skipped_features: usize,
}

/// An upper bound of the number of values in a JSON text, counted without parsing: every
/// value but the first follows a `,` or opens right after a `[` / `{` / `:`, so commas plus
/// opening brackets plus colons plus one bounds it (bytes inside strings are skipped).
pub(crate) fn count_json_values(text: &[u8]) -> u64 {
    let mut n = 1u64;
    let mut in_string = false;
    let mut escaped = false;
    for &b in text {
        if in_string {
            if escaped {
                escaped = false;
            } else if b == b'\\' {
                escaped = true;
            } else if b == b'"' {
                in_string = false;
            }
        } else {
            match b {
                b'"' => in_string = true,
                b',' | b'[' | b'{' | b':' => n += 1,
                _ => {}
            }
        }
    }
    n
}

/// Reads a JSON file of at most `limit` bytes and, when `max_values` is given, at most that
/// many values (counted before the parse builds its tree).
pub(crate) fn read_json_bounded(
    path: &Path,
    limit: u64,
    max_values: Option<u64>,
) -> Result<Value, IoError> {
    let file = std::fs::File::open(path).map_err(|e| IoError::file(path, e))?;
    let mut text = Vec::new();
    file.take(limit.saturating_add(1))
        .read_to_end(&mut text)
        .map_err(|e| IoError::file(path, e))?;
    if text.len() as u64 > limit {
        return Err(IoError::InputTooLarge {
            path: path.to_path_buf(),
            limit,
        });
    }
    if let Some(max) = max_values {
        let values = count_json_values(&text);
        if values > max {
            return Err(IoError::LimitExceeded {
                path: path.to_path_buf(),
                what: format!("about {values} JSON values"),
                limit: "max_json_values",
                max,
            });
        }
    }
    serde_json::from_slice(&text).map_err(|source| IoError::JsonSyntax {
        path: path.to_path_buf(),
        source,
    })
}

/// Reads `geojson_map.json` into a [`FloorPlan`] of `width` x `height` metres.
pub fn read_floor_plan(
    path: impl AsRef<Path>,
    width: f64,
    height: f64,
    limits: &Limits,
) -> Result<PlanRead, IoError> {
    let path = path.as_ref();
    let value = read_json_bounded(path, limits.max_json_bytes, Some(limits.max_json_values))?;
    plan_from_geojson(&value, path, width, height, limits)
}

type Rings = Vec<Vec<[f64; 2]>>;

struct Budget {
    vertices_left: usize,
    limit: usize,
}

fn parse_ring(
    v: &Value,
    path: &Path,
    field: &str,
    budget: &mut Budget,
) -> Result<Vec<[f64; 2]>, IoError> {
    let arr = v
        .as_array()
        .ok_or_else(|| IoError::invalid(path, field, "expected an array of positions"))?;
    if arr.len() > budget.vertices_left {
        return Err(IoError::invalid(
            path,
            field,
            format!("more than {} vertices in the plan", budget.limit),
        ));
    }
    budget.vertices_left -= arr.len();
    arr.iter()
        .enumerate()
        .map(|(i, p)| {
            let pos = p.as_array().filter(|a| a.len() >= 2);
            let lon = pos.and_then(|a| a[0].as_f64()).filter(|v| v.is_finite());
            let lat = pos.and_then(|a| a[1].as_f64()).filter(|v| v.is_finite());
            match (lon, lat) {
                (Some(lon), Some(lat)) => Ok([lon, lat]),
                _ => Err(IoError::invalid(
                    path,
                    format!("{field}[{i}]"),
                    "expected a position [lon, lat] of finite numbers",
                )),
            }
        })
        .collect()
}

fn parse_polygon(
    v: &Value,
    path: &Path,
    field: &str,
    budget: &mut Budget,
) -> Result<Rings, IoError> {
    let arr = v
        .as_array()
        .ok_or_else(|| IoError::invalid(path, field, "expected an array of rings"))?;
    arr.iter()
        .enumerate()
        .map(|(i, r)| parse_ring(r, path, &format!("{field}[{i}]"), budget))
        .collect()
}

/// The polygons (each a list of rings) of a Polygon or MultiPolygon geometry; `Ok(None)`
/// for other geometry types.
fn parse_geometry(
    feature: &Value,
    path: &Path,
    field: &str,
    budget: &mut Budget,
) -> Result<Option<Vec<Rings>>, IoError> {
    let geometry = feature.get("geometry").filter(|g| !g.is_null());
    let Some(geometry) = geometry else {
        return Ok(None);
    };
    let coords_field = format!("{field}.geometry.coordinates");
    let coords = geometry.get("coordinates");
    match geometry.get("type").and_then(Value::as_str) {
        Some("Polygon") => {
            let c = coords.ok_or_else(|| IoError::invalid(path, &coords_field, "missing"))?;
            Ok(Some(vec![parse_polygon(c, path, &coords_field, budget)?]))
        }
        Some("MultiPolygon") => {
            let c = coords
                .and_then(Value::as_array)
                .ok_or_else(|| IoError::invalid(path, &coords_field, "expected an array"))?;
            let polys = c
                .iter()
                .enumerate()
                .map(|(i, p)| parse_polygon(p, path, &format!("{coords_field}[{i}]"), budget))
                .collect::<Result<Vec<_>, _>>()?;
            Ok(Some(polys))
        }
        _ => Ok(None),
    }
}

/// Builds the plan from a parsed GeoJSON value (`path` only names the source in errors).
pub fn plan_from_geojson(
    value: &Value,
    path: &Path,
    width: f64,
    height: f64,
    limits: &Limits,
) -> Result<PlanRead, IoError> {
    if !(width.is_finite() && height.is_finite() && width > 0.0 && height > 0.0) {
        return Err(IoError::invalid(
            path,
            "map_info",
            format!("invalid floor size {width} x {height} m"),
        ));
    }
    let features = value
        .get("features")
        .and_then(Value::as_array)
        .ok_or_else(|| IoError::invalid(path, "features", "expected an array of features"))?;
    if features.len() > limits.max_geojson_features {
        return Err(IoError::invalid(
            path,
            "features",
            format!(
                "{} features, more than the limit of {}",
                features.len(),
                limits.max_geojson_features
            ),
        ));
    }
    let mut budget = Budget {
        vertices_left: limits.max_geojson_vertices,
        limit: limits.max_geojson_vertices,
    };
    let first = features.first().ok_or_else(|| {
        IoError::invalid(
            path,
            "features",
            "no features (the first must be the floor outline)",
        )
    })?;
    let outline_polys =
        parse_geometry(first, path, "features[0]", &mut budget)?.ok_or_else(|| {
            IoError::invalid(
                path,
                "features[0].geometry",
                "the floor outline must be a Polygon or MultiPolygon",
            )
        })?;
    let mut bbox = LonLatBox {
        min_lon: f64::INFINITY,
        min_lat: f64::INFINITY,
        max_lon: f64::NEG_INFINITY,
        max_lat: f64::NEG_INFINITY,
    };
    for p in outline_polys.iter().flatten().flatten() {
        bbox.min_lon = bbox.min_lon.min(p[0]);
        bbox.max_lon = bbox.max_lon.max(p[0]);
        bbox.min_lat = bbox.min_lat.min(p[1]);
        bbox.max_lat = bbox.max_lat.max(p[1]);
    }
    if !bbox.is_valid() {
        return Err(IoError::invalid(
            path,
            "features[0].geometry.coordinates",
            "the floor outline's bounding box is empty or degenerate",
        ));
    }
    let sx = width / (bbox.max_lon - bbox.min_lon);
    let sy = height / (bbox.max_lat - bbox.min_lat);
    let to_m = |p: &[f64; 2]| Point2::new((p[0] - bbox.min_lon) * sx, (p[1] - bbox.min_lat) * sy);
    // A ring is usable when it has area and does not cross itself: a bow tie has no inside
    // a point-in-polygon test can agree on, and its edges would become walls across a room.
    // Outline, unit and hole rings are checked alike.
    let to_polygon = |rings: &Rings| -> Result<Polygon, &'static str> {
        let mut it = rings.iter().map(|r| r.iter().map(to_m).collect::<Vec<_>>());
        let exterior = it.next().ok_or("degenerate")?;
        let holes: Vec<Vec<Point2>> = it
            .filter_map(|mut h| {
                if h.len() > 1 && h.first() == h.last() {
                    h.pop();
                }
                (h.len() >= 3).then_some(h)
            })
            .collect();
        // Zero area (collinear or repeated vertices): nothing to be inside of.
        let min_area = 1e-9 * width * height;
        if ring_area(&exterior).abs() <= min_area {
            return Err("degenerate");
        }
        if self_intersects(&exterior) || holes.iter().any(|h| self_intersects(h)) {
            return Err("self-intersecting");
        }
        Polygon::new(exterior, holes).map_err(|_| "degenerate")
    };
    let mut skipped = 0usize;
    let mut outline = Vec::new();
    for (i, rings) in outline_polys.iter().enumerate() {
        match to_polygon(rings) {
            Ok(p) => outline.push(p),
            Err(why) => {
                skipped += 1;
                tracing::warn!(file = %path.display(), part = i, "{why} outline polygon skipped");
            }
        }
    }
    if outline.is_empty() {
        return Err(IoError::invalid(
            path,
            "features[0].geometry.coordinates",
            "no polygon of the floor outline has three distinct vertices",
        ));
    }
    let mut units = Vec::new();
    for (i, feature) in features.iter().enumerate().skip(1) {
        let field = format!("features[{i}]");
        let name = feature
            .get("properties")
            .and_then(|p| p.get("name"))
            .and_then(Value::as_str)
            .unwrap_or("")
            .to_string();
        match parse_geometry(feature, path, &field, &mut budget)? {
            None => {
                skipped += 1;
                tracing::debug!(file = %path.display(), feature = i, "non-polygon feature skipped");
            }
            Some(polys) => {
                for (part, rings) in polys.iter().enumerate() {
                    match to_polygon(rings) {
                        Ok(polygon) => units.push(Unit {
                            name: name.clone(),
                            polygon,
                        }),
                        Err(why) => {
                            skipped += 1;
                            if why == "degenerate" {
                                tracing::debug!(file = %path.display(), feature = i, part, unit = %name, "degenerate unit polygon skipped");
                            } else {
                                tracing::warn!(file = %path.display(), feature = i, part, unit = %name, "{why} unit polygon skipped");
                            }
                        }
                    }
                }
            }
        }
    }
    let plan = FloorPlan::new(width, height, outline, units)
        .map_err(|e| IoError::invalid(path, "map_info", e.to_string()))?;
    Ok(PlanRead {
        plan,
        lonlat_box: bbox,
        skipped_features: skipped,
    })
}

/// Signed area of a ring (shoelace), square metres.
fn ring_area(ring: &[Point2]) -> f64 {
    let n = ring.len();
    (0..n)
        .map(|i| {
            let (a, b) = (ring[i], ring[(i + 1) % n]);
            a.x * b.y - b.x * a.y
        })
        .sum::<f64>()
        / 2.0
}

/// Most ring vertices checked for self-intersection (the check is quadratic); longer rings
/// are taken as they are (logged at debug).
pub const MAX_SELF_INTERSECTION_CHECK: usize = 4096;

/// Whether two edges of the closed ring cross (adjacent edges sharing their vertex do not
/// count).
fn self_intersects(ring: &[Point2]) -> bool {
    let n = ring.len();
    if n < 4 {
        return false;
    }
    if n > MAX_SELF_INTERSECTION_CHECK {
        tracing::debug!(
            vertices = n,
            "ring too long for the self-intersection check"
        );
        return false;
    }
    let cross =
        |o: Point2, a: Point2, b: Point2| (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x);
    let proper = |p1: Point2, p2: Point2, q1: Point2, q2: Point2| {
        let d1 = cross(q1, q2, p1);
        let d2 = cross(q1, q2, p2);
        let d3 = cross(p1, p2, q1);
        let d4 = cross(p1, p2, q2);
        ((d1 > 0.0 && d2 < 0.0) || (d1 < 0.0 && d2 > 0.0))
            && ((d3 > 0.0 && d4 < 0.0) || (d3 < 0.0 && d4 > 0.0))
    };
    for i in 0..n {
        let (a1, a2) = (ring[i], ring[(i + 1) % n]);
        for j in i + 2..n {
            if i == 0 && j == n - 1 {
                continue; // adjacent through the closing vertex
            }
            let (b1, b2) = (ring[j], ring[(j + 1) % n]);
            if proper(a1, a2, b1, b2) {
                return true;
            }
        }
    }
    false
}

/// Writes `plan` as a GeoJSON FeatureCollection in degrees: the first feature is the floor
/// outline (a MultiPolygon), the others one Polygon per unit with a `name` property.
/// `[0, width] x [0, height]` metres is mapped linearly onto `lonlat_box`. Reading it back
/// with [`read_floor_plan`] gives the plan again when the outline spans the whole
/// `[0, width] x [0, height]` (as the reader maps the outline's bounding box onto it).
/// Deterministic output.
pub fn write_floor_plan(
    path: impl AsRef<Path>,
    plan: &FloorPlan,
    lonlat_box: LonLatBox,
) -> Result<(), IoError> {
    let path = path.as_ref();
    let value = floor_plan_to_geojson(plan, lonlat_box)?;
    let mut file =
        std::io::BufWriter::new(std::fs::File::create(path).map_err(|e| IoError::file(path, e))?);
    serde_json::to_writer(&mut file, &value).map_err(|e| IoError::file(path, e.into()))?;
    file.flush().map_err(|e| IoError::file(path, e))
}

/// The GeoJSON value [`write_floor_plan`] writes.
pub fn floor_plan_to_geojson(plan: &FloorPlan, lonlat_box: LonLatBox) -> Result<Value, IoError> {
    if !lonlat_box.is_valid() {
        return Err(IoError::Unwritable {
            field: "lonlat_box".into(),
            message: format!("degenerate or non-finite box {lonlat_box:?}"),
        });
    }
    if !(plan.width > 0.0 && plan.height > 0.0 && plan.width.is_finite() && plan.height.is_finite())
    {
        return Err(IoError::Unwritable {
            field: "plan.width/height".into(),
            message: format!("invalid floor size {} x {}", plan.width, plan.height),
        });
    }
    let b = lonlat_box;
    let to_deg = |p: &Point2| -> Value {
        json!([
            b.min_lon + p.x / plan.width * (b.max_lon - b.min_lon),
            b.min_lat + p.y / plan.height * (b.max_lat - b.min_lat)
        ])
    };
    let ring = |r: &[Point2]| -> Value {
        let mut pts: Vec<Value> = r.iter().map(to_deg).collect();
        if let Some(first) = r.first() {
            pts.push(to_deg(first)); // GeoJSON rings are closed
        }
        Value::Array(pts)
    };
    let polygon = |p: &Polygon| -> Value {
        let mut rings = vec![ring(&p.exterior)];
        rings.extend(p.holes.iter().map(|h| ring(h)));
        Value::Array(rings)
    };
    if let Some((lo, hi)) = outline_bbox(plan) {
        let tol = 1e-6 * plan.width.max(plan.height);
        if lo.x.abs() > tol
            || lo.y.abs() > tol
            || (hi.x - plan.width).abs() > tol
            || (hi.y - plan.height).abs() > tol
        {
            tracing::warn!(
                "floor outline spans ({:.3}, {:.3})-({:.3}, {:.3}), not [0, {}] x [0, {}]: the reader's transform will not give the same coordinates back",
                lo.x,
                lo.y,
                hi.x,
                hi.y,
                plan.width,
                plan.height
            );
        }
    }
    let mut features = vec![json!({
        "type": "Feature",
        "geometry": {
            "type": "MultiPolygon",
            "coordinates": plan.outline.iter().map(polygon).collect::<Vec<_>>(),
        },
        "properties": {"name": "outline", "type": "floor"},
    })];
    features.extend(plan.units.iter().map(|u| {
        json!({
            "type": "Feature",
            "geometry": {"type": "Polygon", "coordinates": polygon(&u.polygon)},
            "properties": {"name": u.name},
        })
    }));
    Ok(json!({"type": "FeatureCollection", "features": features}))
}

fn outline_bbox(plan: &FloorPlan) -> Option<(Point2, Point2)> {
    let mut it = plan.outline.iter().map(Polygon::bbox);
    let first = it.next()?;
    Some(it.fold(first, |(lo, hi), (l, h)| {
        (
            Point2::new(lo.x.min(l.x), lo.y.min(l.y)),
            Point2::new(hi.x.max(h.x), hi.y.max(h.y)),
        )
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rect(x0: f64, y0: f64, x1: f64, y1: f64) -> Polygon {
        Polygon::rectangle(x0, y0, x1, y1).unwrap()
    }

    fn sample_plan() -> FloorPlan {
        FloorPlan::new(
            40.0,
            20.0,
            vec![rect(0.0, 0.0, 40.0, 20.0)],
            vec![
                Unit {
                    name: "shop A".into(),
                    polygon: rect(2.0, 2.0, 10.0, 8.0),
                },
                Unit {
                    name: String::new(),
                    polygon: rect(20.0, 12.0, 30.0, 18.0),
                },
            ],
        )
        .unwrap()
    }

    #[test]
    fn write_then_read_round_trips() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("geojson_map.json");
        let plan = sample_plan();
        let bbox = LonLatBox::around(120.07, 30.29, 40.0, 20.0);
        write_floor_plan(&path, &plan, bbox).unwrap();
        let first = std::fs::read(&path).unwrap();
        write_floor_plan(&path, &plan, bbox).unwrap();
        assert_eq!(first, std::fs::read(&path).unwrap(), "deterministic");
        let back = read_floor_plan(&path, 40.0, 20.0, &Limits::default()).unwrap();
        assert_eq!(back.skipped_features, 0);
        assert_eq!(back.plan.units.len(), 2);
        assert_eq!(back.plan.units[0].name, "shop A");
        for (a, b) in back.plan.units.iter().zip(&plan.units) {
            for (p, q) in a.polygon.exterior.iter().zip(&b.polygon.exterior) {
                assert!((p - q).norm() < 1e-6, "{p} vs {q}");
            }
        }
        assert!((back.lonlat_box.max_lon - bbox.max_lon).abs() < 1e-12);
        assert!(back.plan.is_walkable(Point2::new(15.0, 10.0)));
        assert!(!back.plan.is_walkable(Point2::new(5.0, 5.0)));
    }

    #[test]
    fn bad_geojson_gives_typed_errors() {
        let limits = Limits {
            max_geojson_vertices: 10,
            ..Limits::default()
        };
        let p = Path::new("g.json");
        let cases = [
            (json!({}), "features"),
            (json!({"features": []}), "features"),
            (
                json!({"features": [{"geometry": {"type": "Point", "coordinates": [1, 2]}}]}),
                "features[0].geometry",
            ),
            (
                json!({"features": [{"geometry": {"type": "Polygon", "coordinates": [[[1, 2], [1, "x"], [3, 3]]]}}]}),
                "features[0].geometry.coordinates[0][1]",
            ),
            (
                json!({"features": [{"geometry": {"type": "Polygon", "coordinates": [[[1, 2], [1, 2], [1, 2]]]}}]}),
                "features[0].geometry.coordinates",
            ),
        ];
        for (v, field) in cases {
            match plan_from_geojson(&v, p, 10.0, 10.0, &limits) {
                Err(IoError::Invalid { field: f, .. }) => assert_eq!(f, field, "{v}"),
                other => panic!("{v}: {other:?}"),
            }
        }
        let big: Vec<Value> = (0..20).map(|i| json!([i, i * i])).collect();
        let v = json!({"features": [{"geometry": {"type": "Polygon", "coordinates": [big]}}]});
        let e = plan_from_geojson(&v, p, 10.0, 10.0, &limits).unwrap_err();
        assert!(e.to_string().contains("more than 10 vertices"), "{e}");
    }
}
