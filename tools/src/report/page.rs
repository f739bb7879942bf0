//! The report page: one self-contained HTML file rendered from the results JSON value by a
//! minijinja template (`tools/templates/report.html`), with the page's style and script
//! (`report.css`, `report.js`) and its data inlined; nothing is loaded from the network.
//!
//! The tables are rendered here (they read without a script); the script sorts them, draws the
//! error CDF and the chosen walk (SVG), and fills the readout of the time slider.

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};
use serde_json::{Value, json};
use std::collections::BTreeMap;
use wipdr_eval::drawing::{DrawnPoint, TimedPoint};
use wipdr_eval::report::Summary;

/// The only floor images the page draws: embedded PNGs.
const PNG_DATA_URL: &str = "data:image/png;base64,";

/// A scored point as the JSON has it: `[t_ms, error_m or null, floor_error or null]`.
type PageScored = (i64, Option<f64>, Option<i32>);

static TEMPLATE: &str = include_str!("../../templates/report.html");
static STYLE: &str = include_str!("../../templates/report.css");
static SCRIPT: &str = include_str!("../../templates/report.js");

/// The colours of the schemes, in order: those of the PNG plots (`plotting::palette`), then
/// four more so that all thirteen built-in schemes differ.
const PALETTE: [&str; 16] = [
    "#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f",
    "#bcbd22", "#17becf", "#800000", "#ffd700", "#000080", "#008080", "#ff1493", "#556b2f",
];

/// The parts of the results JSON the page reads (`wipdr_eval::report` lists the schema).
#[derive(Debug, Deserialize)]
struct Results {
    pooled: BTreeMap<String, Summary>,
    floors: BTreeMap<String, BTreeMap<String, Summary>>,
    walks: Vec<WalkEntry>,
    schemes: Vec<String>,
    config: Value,
    #[serde(default)]
    walk_data: Vec<WalkData>,
    #[serde(default)]
    plans: BTreeMap<String, Value>,
    #[serde(default)]
    drawing: Option<Value>,
}

#[derive(Debug, Deserialize)]
struct WalkEntry {
    floor: String,
    walk: String,
    fold: usize,
    scheme: String,
    count: usize,
    /// `null` in the JSON where nothing was scored (a NaN mean).
    mean: Option<f64>,
    errors: Vec<PageScored>,
    #[serde(default)]
    sd_m: Option<Vec<Option<f64>>>,
    #[serde(default)]
    track: Option<Vec<DrawnPoint>>,
}

#[derive(Debug, Deserialize)]
struct WalkData {
    floor: String,
    walk: String,
    waypoints: Vec<TimedPoint>,
    fixes: Vec<TimedPoint>,
}

/// A table cell: its text and the value it sorts by (empty: sorts last).
#[derive(Debug, Serialize)]
struct Cell {
    text: String,
    sort: String,
}

impl Cell {
    fn text(s: &str) -> Self {
        Self {
            text: s.to_owned(),
            sort: String::new(),
        }
    }

    fn num(v: Option<f64>, decimals: usize) -> Self {
        match v.filter(|v| v.is_finite()) {
            Some(v) => Self {
                text: format!("{v:.decimals$}"),
                sort: format!("{v}"),
            },
            None => Self {
                text: "–".to_owned(),
                sort: String::new(),
            },
        }
    }

    fn share(v: Option<f64>) -> Self {
        let mut c = Self::num(v.map(|v| 100.0 * v), 1);
        if v.is_some_and(f64::is_finite) {
            c.text.push_str(" %");
        }
        c
    }
}

#[derive(Debug, Serialize)]
struct Table {
    title: String,
    columns: Vec<&'static str>,
    rows: Vec<Vec<Cell>>,
}

/// One line of the walk picker.
#[derive(Debug, Serialize)]
struct WalkRow {
    /// Index into the page data's `walks`.
    index: usize,
    cells: Vec<Cell>,
}

/// One walk as the script draws it.
#[derive(Debug, Serialize)]
struct PageWalk {
    floor: String,
    walk: String,
    fold: usize,
    truth: Vec<TimedPoint>,
    fixes: Vec<TimedPoint>,
    /// Per scheme (in the run's order; `null` where the run has no result).
    results: Vec<Option<PageResult>>,
}

#[derive(Debug, Serialize)]
struct PageResult {
    mean: Option<f64>,
    errors: Vec<PageScored>,
    sd_m: Option<Vec<Option<f64>>>,
    track: Option<Vec<DrawnPoint>>,
}

fn summary_table(title: String, schemes: &[String], rows: &BTreeMap<String, Summary>) -> Table {
    let floors = rows.values().any(|s| s.floor_hit_rate.is_some());
    let radius = rows.values().any(|s| s.radius_95_coverage.is_some());
    let mut columns = vec![
        "scheme", "count", "skipped", "mean", "rms", "p50", "p75", "p95", "max",
    ];
    if floors {
        columns.extend(["floor hit", "EvAAL"]);
    }
    if radius {
        columns.push("r95 %");
    }
    let rows = schemes
        .iter()
        .filter_map(|s| rows.get(s).map(|r| (s, r)))
        .map(|(s, r)| {
            let mut cells = vec![
                Cell::text(s),
                Cell::num(Some(r.count as f64), 0),
                Cell::num(Some(r.skipped as f64), 0),
            ];
            cells
                .extend([r.mean, r.rms, r.p50, r.p75, r.p95, r.max].map(|v| Cell::num(Some(v), 2)));
            if floors {
                cells.push(Cell::share(r.floor_hit_rate));
                cells.push(Cell::num(r.evaal, 2));
            }
            if radius {
                cells.push(Cell::share(r.radius_95_coverage));
            }
            cells
        })
        .collect();
    Table {
        title,
        columns,
        rows,
    }
}

/// What the template sees.
#[derive(Debug, Serialize)]
struct PageContext<'a> {
    schemes: &'a [String],
    walk_count: usize,
    floor_count: usize,
    tables: Vec<Table>,
    walk_rows: Vec<WalkRow>,
    has_tracks: bool,
    /// The run's config, pretty JSON.
    config: String,
    style: &'static str,
    script: &'static str,
    /// The page data for the script ([`script_json`]).
    data: String,
    palette: [&'static str; 16],
}

/// The JSON text of `value` safe inside `<script type="application/json">`: `<`, `>` and
/// `&` (which JSON has only inside strings) written as `\u` escapes, so no `</script>` or
/// `<!--` can end the element early.
fn script_json(value: &impl Serialize) -> Result<String> {
    let text = serde_json::to_string(value)?;
    Ok(text
        .replace('<', "\\u003c")
        .replace('>', "\\u003e")
        .replace('&', "\\u0026"))
}

/// Renders the report page from the results JSON `value` (as `wipdr eval --json` writes it;
/// the drawing fields are optional: without them the page has tables, CDF and walk picker
/// but no tracks). `source` names where the value came from, for errors.
pub fn render(value: &Value, source: &str) -> Result<String> {
    let results: Results = serde_path_to_error::deserialize(value)
        .map_err(|e| anyhow::anyhow!("{source}: field {}: {}", e.path(), e.inner()))?;
    let schemes = &results.schemes;
    if schemes.is_empty() {
        anyhow::bail!("{source}: field schemes: the run lists no scheme");
    }
    let scheme_index: BTreeMap<&str, usize> = schemes
        .iter()
        .enumerate()
        .map(|(i, s)| (s.as_str(), i))
        .collect();
    let mut tables = vec![summary_table(
        "Pooled over all floors".to_owned(),
        schemes,
        &results.pooled,
    )];
    for (floor, rows) in &results.floors {
        tables.push(summary_table(format!("Floor {floor}"), schemes, rows));
    }
    // The walks, in the order of the run, each with its per-scheme results.
    let mut walks: Vec<PageWalk> = Vec::new();
    let mut walk_index: BTreeMap<(String, String), usize> = BTreeMap::new();
    for (i, entry) in results.walks.into_iter().enumerate() {
        let Some(&s) = scheme_index.get(entry.scheme.as_str()) else {
            anyhow::bail!(
                "{source}: field walks[{i}].scheme: {:?} is not among the run's schemes",
                entry.scheme
            );
        };
        let key = (entry.floor.clone(), entry.walk.clone());
        let w = *walk_index.entry(key).or_insert_with(|| {
            walks.push(PageWalk {
                floor: entry.floor.clone(),
                walk: entry.walk.clone(),
                fold: entry.fold,
                truth: Vec::new(),
                fixes: Vec::new(),
                results: (0..schemes.len()).map(|_| None).collect(),
            });
            walks.len() - 1
        });
        walks[w].results[s] = Some(PageResult {
            mean: entry.mean.filter(|_| entry.count > 0),
            errors: entry.errors,
            sd_m: entry.sd_m,
            track: entry.track,
        });
    }
    for d in results.walk_data {
        if let Some(&w) = walk_index.get(&(d.floor, d.walk)) {
            walks[w].truth = d.waypoints;
            walks[w].fixes = d.fixes;
        }
    }
    let has_tracks = walks
        .iter()
        .any(|w| w.results.iter().flatten().any(|r| r.track.is_some()));
    // The picker: worst first by the mean error of the last scheme listed (as
    // `eval --plot-worst`), walks without a result for it last.
    let last = schemes.len() - 1;
    let mean_of = |w: &PageWalk| {
        w.results[last]
            .as_ref()
            .and_then(|r| r.mean)
            .filter(|m| m.is_finite())
    };
    let mut order: Vec<usize> = (0..walks.len()).collect();
    order.sort_by(|&a, &b| {
        let (ma, mb) = (mean_of(&walks[a]), mean_of(&walks[b]));
        mb.unwrap_or(f64::NEG_INFINITY)
            .total_cmp(&ma.unwrap_or(f64::NEG_INFINITY))
    });
    let walk_rows: Vec<WalkRow> = order
        .iter()
        .map(|&i| {
            let w = &walks[i];
            let mut cells = vec![
                Cell::text(&w.floor),
                Cell::text(&w.walk),
                Cell::num(Some(w.fold as f64), 0),
            ];
            cells.extend(
                w.results
                    .iter()
                    .map(|r| Cell::num(r.as_ref().and_then(|r| r.mean), 2)),
            );
            WalkRow { index: i, cells }
        })
        .collect();
    // A floor image is drawn only as what `wipdr eval` embeds (a PNG data URL): a results
    // file from elsewhere may hold any text there.
    let mut plans = results.plans;
    for plan in plans.values_mut() {
        if let Some(fields) = plan.as_object_mut()
            && !fields
                .get("image")
                .and_then(Value::as_str)
                .is_some_and(|s| s.starts_with(PNG_DATA_URL))
        {
            fields.remove("image");
        }
    }
    let floor_count = results.floors.len();
    let data = json!({
        "schemes": schemes,
        "palette": PALETTE,
        "walks": walks,
        "plans": plans,
        "has_tracks": has_tracks,
        "drawing": results.drawing,
    });
    let mut env = minijinja::Environment::new();
    env.add_template("report.html", TEMPLATE)
        .context("the report template")?;
    let page = env
        .get_template("report.html")
        .context("the report template")?
        .render(minijinja::value::Serde(&PageContext {
            schemes,
            walk_count: walks.len(),
            floor_count,
            tables,
            walk_rows,
            has_tracks,
            config: serde_json::to_string_pretty(&results.config)?,
            style: STYLE,
            script: SCRIPT,
            data: script_json(&data)?,
            palette: PALETTE,
        }))
        .context("rendering the report page")?;
    Ok(page)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn minimal() -> Value {
        let summary = json!({"count": 2, "skipped": 0, "mean": 1.5, "rms": 1.6, "p50": 1.5,
            "p75": 1.8, "p95": 2.0, "max": 2.0});
        json!({
            "pooled": {"wifi": summary},
            "floors": {"F1": {"wifi": summary}},
            "walks": [
                {"floor": "F1", "walk": "a</script><b>", "fold": 0, "scheme": "wifi", "count": 2,
                 "skipped": 0, "mean": 1.5, "p95": 2.0, "max": 2.0,
                 "errors": [[0, 1.0, 0], [1000, 2.0, 0]]},
                {"floor": "F1", "walk": "b", "fold": 1, "scheme": "wifi", "count": 2,
                 "skipped": 0, "mean": 3.5, "p95": 4.0, "max": 4.0,
                 "errors": [[0, 3.0, 0], [1000, 4.0, 0]]}
            ],
            "schemes": ["wifi"],
            "config": {"seed": 7},
        })
    }

    #[test]
    fn a_json_without_tracks_renders_tables_and_picker_escaped_worst_first() {
        let page = render(&minimal(), "t.json").unwrap();
        // The walk id is escaped in the picker and in the data (no early end of a script).
        assert!(page.contains("a&lt;&#x2f;script&gt;&lt;b&gt;"));
        assert_eq!(
            page.matches("</script>").count(),
            2,
            "data and script elements"
        );
        assert!(page.contains("a\\u003c/script\\u003e\\u003cb\\u003e"));
        // Worst first: walk b (3.5 m) before walk a (1.5 m).
        let (b, a) = (
            page.find(">b<").unwrap(),
            page.find("a&lt;&#x2f;script").unwrap(),
        );
        assert!(b < a);
        assert!(page.contains(r#"data-has-tracks="false""#));
        // Nothing from the network.
        for needle in ["src=\"http", "href=\"http", "url(http", "@import", "<link"] {
            assert!(!page.contains(needle), "{needle}");
        }
    }

    #[test]
    fn bad_fields_are_named() {
        let mut v = minimal();
        v["walks"][1]["fold"] = json!("one");
        let err = format!("{:#}", render(&v, "r.json").unwrap_err());
        assert!(
            err.contains("r.json") && err.contains("walks[1].fold"),
            "{err}"
        );
        let mut v = minimal();
        v["walks"][0]["scheme"] = json!("ekf");
        let err = format!("{:#}", render(&v, "r.json").unwrap_err());
        assert!(err.contains("walks[0].scheme"), "{err}");
        let mut v = minimal();
        v.as_object_mut().unwrap().remove("pooled");
        let err = format!("{:#}", render(&v, "r.json").unwrap_err());
        assert!(err.contains("pooled"), "{err}");
    }
}
