//! The drawing data of a run, added to the results JSON: each walk result's downsampled
//! track, each walk's truth and Wi-Fi fixes, each floor's plan (walls, and its image as a
//! base64 PNG). The fields are listed in `wipdr_eval::report`'s JSON schema; the rule of the
//! downsampling in [`wipdr_eval::drawing`].

use anyhow::{Context, Result};
use base64::Engine;
use serde_json::{Value, json};
use std::collections::HashMap;
use std::sync::Mutex;
use wipdr_eval::drawing::{self, DrawnPoint};
use wipdr_eval::pipeline::{FloorInput, PreparedWalk};
use wipdr_eval::scoring::Track;

/// The drawn tracks of a run, filled while the schemes run (from
/// [`wipdr_eval::pipeline::run_prepared_observed`]'s callback, in parallel).
#[derive(Debug)]
pub struct TrackStore {
    schemes: usize,
    tracks: Mutex<Vec<Option<Vec<DrawnPoint>>>>,
}

impl TrackStore {
    /// An empty store for `walks` prepared walks times `schemes` schemes.
    pub fn new(walks: usize, schemes: usize) -> Self {
        Self {
            schemes,
            tracks: Mutex::new(vec![None; walks * schemes]),
        }
    }

    /// Keeps the drawn form of the track of scheme `scheme` on prepared walk `walk`.
    pub fn keep(&self, prepared: &[PreparedWalk], walk: usize, scheme: usize, track: &Track) {
        let drawn = drawing::drawn_track(track, &prepared[walk].waypoints);
        let mut tracks = self
            .tracks
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        if let Some(slot) = tracks.get_mut(walk * self.schemes + scheme) {
            *slot = Some(drawn);
        }
    }

    fn into_tracks(self) -> Vec<Option<Vec<DrawnPoint>>> {
        self.tracks
            .into_inner()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
    }
}

/// Adds the drawing data to `value` (the results JSON of `wipdr eval --json`): `"track"` to
/// each entry of `"walks"` (matched by floor, walk and scheme), and the top-level
/// `"walk_data"`, `"plans"` and `"drawing"`.
pub fn add_drawing(
    value: &mut Value,
    floors: &[FloorInput],
    prepared: &[PreparedWalk],
    schemes: &[String],
    store: TrackStore,
) -> Result<()> {
    let tracks = store.into_tracks();
    let mut by_key: HashMap<(&str, &str, &str), Vec<DrawnPoint>> = HashMap::new();
    for (w, pw) in prepared.iter().enumerate() {
        for (s, scheme) in schemes.iter().enumerate() {
            if let Some(Some(t)) = tracks.get(w * schemes.len() + s) {
                by_key.insert((&pw.floor, &pw.walk, scheme), t.clone());
            }
        }
    }
    if let Some(walks) = value.get_mut("walks").and_then(Value::as_array_mut) {
        for entry in walks {
            let key = |k: &str| entry.get(k).and_then(Value::as_str).map(str::to_owned);
            if let (Some(f), Some(w), Some(s)) = (key("floor"), key("walk"), key("scheme"))
                && let Some(track) = by_key.get(&(f.as_str(), w.as_str(), s.as_str()))
            {
                entry["track"] = json!(track);
            }
        }
    }
    let walk_data: Vec<Value> = prepared
        .iter()
        .map(|pw| {
            json!({
                "floor": pw.floor,
                "walk": pw.walk,
                "fold": pw.fold,
                "waypoints": drawing::drawn_waypoints(&pw.waypoints),
                "fixes": drawing::drawn_fixes(&pw.observations),
            })
        })
        .collect();
    let mut plans = serde_json::Map::new();
    for f in floors {
        plans.insert(f.label.clone(), plan_of(f)?);
    }
    value["walk_data"] = Value::Array(walk_data);
    value["plans"] = Value::Object(plans);
    value["drawing"] = json!({ "tolerance_m": drawing::DRAW_TOLERANCE_M });
    Ok(())
}

/// A floor's plan as drawn: size, walls, and its image (`floor_image.png` beside the walks,
/// where the floor has one) as a `data:` URL.
fn plan_of(floor: &FloorInput) -> Result<Value> {
    let plan = &floor.data.plan;
    let image = match &floor.dir {
        Some(dir) => {
            let path = dir.join(crate::plotting::FloorImage::FILE_NAME);
            if path.is_file() {
                let bytes =
                    std::fs::read(&path).with_context(|| format!("reading {}", path.display()))?;
                // As the PNG plots do: an image that does not decode is named in a warning
                // and the page draws the vector plan instead.
                match image::load_from_memory_with_format(&bytes, image::ImageFormat::Png) {
                    Ok(_) => Some(format!(
                        "data:image/png;base64,{}",
                        base64::engine::general_purpose::STANDARD.encode(&bytes)
                    )),
                    Err(e) => {
                        tracing::warn!(
                            "{} unusable ({e}): the report draws the vector plan",
                            path.display()
                        );
                        None
                    }
                }
            } else {
                None
            }
        }
        None => None,
    };
    Ok(json!({
        "width": plan.width,
        "height": plan.height,
        "walls": drawing::drawn_walls(plan),
        "image": image,
    }))
}
