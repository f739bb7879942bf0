//! The report page (`wipdr eval --report`, `wipdr report`) in a real browser: headless
//! Chromium loads the page, runs its script, and the test reads the rendered DOM: every walk
//! in the picker, a trajectory drawn, no script error. Where no Chromium is installed
//! (`.ci/run` installs Debian's `chromium`), the browser part skips with a printed reason;
//! the checks of the page's text still run.

use serde_json::Value;
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::Command;

mod common;
use common::{chromium, wipdr};

/// What the page's script left in the DOM.
#[derive(Debug)]
struct Rendered {
    dom: String,
    stderr: String,
}

impl Rendered {
    /// The attribute `name` of the element with id `id`.
    fn attribute(&self, id: &str, name: &str) -> Option<String> {
        let start = self.dom.find(&format!("id=\"{id}\""))?;
        let open = self.dom[..start].rfind('<')?;
        let tag = &self.dom[open..open + self.dom[open..].find('>')?];
        let at = tag.find(&format!(" {name}=\""))? + name.len() + 3;
        Some(tag[at..at + tag[at..].find('"')?].to_owned())
    }

    /// The text inside the element with id `id` (up to its first child or end).
    fn text_of(&self, id: &str) -> Option<&str> {
        let start = self.dom.find(&format!("id=\"{id}\""))?;
        let from = start + self.dom[start..].find('>')? + 1;
        Some(&self.dom[from..from + self.dom[from..].find('<')?])
    }
}

/// Loads `page` in headless Chromium and returns the DOM after its script ran.
fn render(browser: &Path, page: &Path) -> Rendered {
    let profile = tempfile::tempdir().unwrap();
    let out = Command::new(browser)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--enable-logging=stderr",
            "--v=0",
            "--virtual-time-budget=20000",
        ])
        .arg(format!("--user-data-dir={}", profile.path().display()))
        .arg("--dump-dom")
        .arg(format!("file://{}", page.canonicalize().unwrap().display()))
        .output()
        .expect("chromium runs");
    assert!(
        out.status.success(),
        "chromium failed on {}: {}",
        page.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    Rendered {
        dom: String::from_utf8_lossy(&out.stdout).into_owned(),
        stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
    }
}

/// The distinct walks of a results JSON.
fn walks_of(results: &Value) -> BTreeSet<(String, String)> {
    results["walks"]
        .as_array()
        .unwrap()
        .iter()
        .map(|w| {
            (
                w["floor"].as_str().unwrap().to_owned(),
                w["walk"].as_str().unwrap().to_owned(),
            )
        })
        .collect()
}

/// The checks on a rendered page: the script ran without error, listed `walks` walks in the
/// picker, and drew at least `min_tracks` trajectories of the chosen walk (with points).
fn check_rendered(r: &Rendered, walks: usize, min_tracks: usize) {
    assert_eq!(
        r.text_of("script-errors"),
        Some(""),
        "script errors in the page"
    );
    assert!(
        !r.stderr.contains("Uncaught"),
        "console error: {}",
        r.stderr
            .lines()
            .filter(|l| l.contains("Uncaught"))
            .collect::<Vec<_>>()
            .join("\n")
    );
    assert_eq!(
        r.attribute("report-status", "data-state").as_deref(),
        Some("ready"),
        "the page's script did not finish"
    );
    assert_eq!(r.dom.matches("class=\"walk-row").count(), walks);
    assert_eq!(
        r.attribute("report-status", "data-walks-listed"),
        Some(walks.to_string())
    );
    let drawn: usize = r
        .attribute("report-status", "data-tracks-drawn")
        .and_then(|v| v.parse().ok())
        .unwrap_or(0);
    assert!(drawn >= min_tracks, "{drawn} tracks drawn");
    let polylines = r
        .dom
        .match_indices("<polyline class=\"track\"")
        .filter(|(at, _)| {
            let tag = &r.dom[*at..*at + r.dom[*at..].find('>').unwrap()];
            tag.split(" points=\"")
                .nth(1)
                .is_some_and(|p| p.contains(','))
        })
        .count();
    assert_eq!(polylines, drawn, "tracks with points in the DOM");
}

fn browser_or_skip() -> Option<PathBuf> {
    let b = chromium();
    if b.is_none() {
        eprintln!(
            "skipped the browser part: no chromium on PATH (nor $WIPDR_CHROMIUM); \
             `apt-get install chromium` brings it"
        );
    }
    b
}

#[test]
fn the_fixture_report_renders_in_chromium_and_equals_the_one_from_its_json() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../fixtures/sim/F1"));
    let schemes = wipdr_fusion::scheme_names().join(",");
    let (page, json) = (tmp.path().join("r.html"), tmp.path().join("r.json"));
    wipdr(
        &[
            "eval",
            "--data",
            dir.to_str().unwrap(),
            "--schemes",
            &schemes,
            "--report",
            page.to_str().unwrap(),
            "--json",
            json.to_str().unwrap(),
            "--json-tracks",
        ],
        tmp.path(),
    );
    // The page from the saved JSON is the page the run wrote.
    let again = tmp.path().join("again.html");
    wipdr(
        &[
            "report",
            json.to_str().unwrap(),
            "--out",
            again.to_str().unwrap(),
        ],
        tmp.path(),
    );
    let html = std::fs::read_to_string(&page).unwrap();
    assert_eq!(html, std::fs::read_to_string(&again).unwrap());
    let results: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let walks = walks_of(&results);
    assert!(walks.len() >= 5, "{} walks", walks.len());
    // Every walk result has its drawn track; every walk its truth.
    for w in results["walks"].as_array().unwrap() {
        assert!(
            !w["track"].as_array().unwrap().is_empty(),
            "{} {}",
            w["walk"],
            w["scheme"]
        );
    }
    assert_eq!(results["walk_data"].as_array().unwrap().len(), walks.len());
    // Self-contained: no element loads anything.
    for needle in ["src=\"http", "href=\"http", "url(http", "@import", "<link"] {
        assert!(!html.contains(needle), "{needle} in the page");
    }

    // The same run's JSON without the drawing data: tables and picker, no tracks.
    let mut bare = results.clone();
    for k in ["walk_data", "plans", "drawing"] {
        bare.as_object_mut().unwrap().remove(k);
    }
    for w in bare["walks"].as_array_mut().unwrap() {
        w.as_object_mut().unwrap().remove("track");
    }
    let (bare_json, bare_page) = (tmp.path().join("bare.json"), tmp.path().join("bare.html"));
    std::fs::write(&bare_json, serde_json::to_string(&bare).unwrap()).unwrap();
    wipdr(
        &[
            "report",
            bare_json.to_str().unwrap(),
            "--out",
            bare_page.to_str().unwrap(),
        ],
        tmp.path(),
    );

    let Some(browser) = browser_or_skip() else {
        return;
    };
    let rendered = render(&browser, &page);
    check_rendered(&rendered, walks.len(), wipdr_fusion::scheme_names().len());
    let rendered = render(&browser, &bare_page);
    check_rendered(&rendered, walks.len(), 0);
    assert!(rendered.dom.contains("no drawing data"));
}

#[test]
fn a_real_floor_report_renders_in_chromium() {
    let dir = match wipdr_io::real_data("ilc20/site2/F3") {
        Ok(dir) => dir,
        Err(missing) => {
            eprintln!("skipped: {missing}");
            return;
        }
    };
    let tmp = tempfile::tempdir().unwrap();
    let (page, json) = (tmp.path().join("r.html"), tmp.path().join("r.json"));
    wipdr(
        &[
            "eval",
            "--data",
            dir.to_str().unwrap(),
            "--schemes",
            "wifi,pdr,ekf,pmf",
            "--report",
            page.to_str().unwrap(),
            "--json",
            json.to_str().unwrap(),
        ],
        tmp.path(),
    );
    let results: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    // `--json` without `--json-tracks` keeps the JSON as it was.
    assert!(results.get("walk_data").is_none());
    assert!(results["walks"][0].get("track").is_none());
    let html = std::fs::read_to_string(&page).unwrap();
    // The floor image is embedded.
    assert!(html.contains("data:image/png;base64,"));
    let Some(browser) = browser_or_skip() else {
        return;
    };
    check_rendered(&render(&browser, &page), walks_of(&results).len(), 4);
}

/// Replaces every string equal to a key of `names` (values and object keys) in `v`.
fn rename_all(v: &mut Value, names: &std::collections::BTreeMap<String, String>) {
    match v {
        Value::String(s) => {
            if let Some(n) = names.get(s.as_str()) {
                *s = n.clone();
            }
        }
        Value::Array(items) => items.iter_mut().for_each(|x| rename_all(x, names)),
        Value::Object(fields) => {
            let old = std::mem::take(fields);
            for (k, mut x) in old {
                rename_all(&mut x, names);
                fields.insert(names.get(&k).cloned().unwrap_or(k), x);
            }
        }
        _ => {}
    }
}

/// Markup, script and template syntax in every string a results JSON carries (scheme names,
/// floor names, walk ids, config keys and values, the plan image) reach the page as text:
/// nothing injected is an element, nothing runs. Seen on the old main: a scheme name went
/// through `innerHTML` in the readout of the chosen walk, and its `onerror` ran.
#[test]
fn crafted_strings_in_a_results_json_reach_the_page_as_text() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../fixtures/sim/F1"));
    let json = tmp.path().join("r.json");
    wipdr(
        &[
            "eval",
            "--data",
            dir.to_str().unwrap(),
            "--schemes",
            "wifi,pdr",
            "--json",
            json.to_str().unwrap(),
            "--json-tracks",
        ],
        tmp.path(),
    );
    let mut results: Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let mut names = std::collections::BTreeMap::new();
    names.insert(
        "wifi".to_owned(),
        r#"<img id="pwned-s" src=x onerror="document.body.dataset.pwned='s'">"#.to_owned(),
    );
    names.insert(
        "pdr".to_owned(),
        r#"{{ 7*7 }}{% raw %}<svg id="pwned-t" onload="document.body.dataset.pwned='t'">"#
            .to_owned(),
    );
    let floor = results["walks"][0]["floor"].as_str().unwrap().to_owned();
    names.insert(
        floor,
        r#""><svg id="pwned-f" onload="document.body.dataset.pwned='f'"></script>"#.to_owned(),
    );
    for (i, w) in walks_of(&results).into_iter().enumerate() {
        names.insert(
            w.1,
            format!(
                r#"</script><script>document.body.dataset.pwned='w{i}'</script><b id="pwned-w{i}">{{{{ walk_count }}}}"#
            ),
        );
    }
    rename_all(&mut results, &names);
    results["config"]["note"] = Value::String(
        r#"{{ 7*7 }}</pre><img id="pwned-c" src=x onerror="document.body.dataset.pwned='c'">"#
            .to_owned(),
    );
    results["config"][r#"<img id="pwned-k" src=x onerror="document.body.dataset.pwned='k'">"#] =
        Value::from(1);
    for plan in results["plans"].as_object_mut().unwrap().values_mut() {
        plan["image"] = Value::String("javascript:document.body.dataset.pwned='i'".to_owned());
    }
    let walks = walks_of(&results).len();
    let (crafted, page) = (
        tmp.path().join("crafted.json"),
        tmp.path().join("crafted.html"),
    );
    std::fs::write(&crafted, serde_json::to_string(&results).unwrap()).unwrap();
    wipdr(
        &[
            "report",
            crafted.to_str().unwrap(),
            "--out",
            page.to_str().unwrap(),
        ],
        tmp.path(),
    );
    let html = std::fs::read_to_string(&page).unwrap();
    for needle in [
        "<img id=\"pwned",
        "<svg id=\"pwned",
        "<b id=\"pwned",
        "javascript:",
    ] {
        assert!(!html.contains(needle), "{needle} in the page's source");
    }
    let Some(browser) = browser_or_skip() else {
        return;
    };
    let r = render(&browser, &page);
    // The page works: its script ran, listed and drew every walk.
    check_rendered(&r, walks, 2);
    // Nothing injected became an element or ran.
    for needle in [
        "<img id=\"pwned",
        "<svg id=\"pwned",
        "<b id=\"pwned",
        "data-pwned",
        "javascript:",
    ] {
        assert!(!r.dom.contains(needle), "{needle} in the rendered page");
    }
    // The strings are there as text, template syntax untouched.
    for text in [
        r#"&lt;img id="pwned-s" src=x onerror="document.body.dataset.pwned='s'"&gt;"#,
        r#"{{ 7*7 }}{% raw %}&lt;svg id="pwned-t""#,
        r#""&gt;&lt;svg id="pwned-f""#,
        r#"&lt;/script&gt;&lt;script&gt;document.body.dataset.pwned='w0'"#,
        "{{ walk_count }}",
        // The config is shown as pretty JSON: its quotes escaped.
        r#"{{ 7*7 }}&lt;/pre&gt;&lt;img id=\"pwned-c\""#,
        r#"&lt;img id=\"pwned-k\""#,
    ] {
        assert!(r.dom.contains(text), "{text} not shown as text");
    }
}
