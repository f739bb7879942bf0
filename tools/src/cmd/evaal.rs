//! `wipdr evaal`: plays an IPIN competition trial through the EvAAL API, as the competition
//! runs its smartphone tracks.
//!
//! ```text
//! wipdr fit --data $WIPDR_DATA/ipin2023 --out ipin.wipdr
//! wipdr evaal --server http://127.0.0.1:5000/evaalapi --trial t1 --model ipin.wipdr --scheme pmf
//! ```
//!
//! Each request `GET <server>/<trial>/nextdata?horizon=H&position=P` posts the estimate `P`
//! for the current trial time and receives the logfile lines of the next `H` seconds; the
//! estimate is computed from the lines received before it, so the run is causal by
//! construction. The estimate posted is the positioner's latest, as it was after the last
//! step or fix received (a row of `wipdr locate`'s track). The first request posts nothing
//! (the server holds the trial's announced initial position); nor does a request while there
//! is no estimate yet, or no floor when the format has one (the scorer needs a floor). The
//! trial ends when the server answers 405 with its final state.
//!
//! **Lines to samples.** Each answer is read as a GetSensorData logfile fragment
//! ([`wipdr_io::logfile::read_logfile_from`]), the sensor lines on the AppTimestamp clock
//! (their SensorTimestamp replaced by it: the offline reader's per-stream median clock
//! offset needs the whole file). Lines sharing an AppTimestamp always come in one answer, so
//! the samples and the estimates are those of `wipdr locate --model` on the served file
//! written the same way (the test `tools/tests/evaal_client.rs` checks it against the
//! official server). The trial gives no header: no phone model or start time, so no
//! barometric references.
//!
//! **Position format** (`--position-format`): the fields `lon`, `lat`, `floor`, `x`, `y`
//! (metres in the model's frame) joined by `,` or `;` as the trial asks; default
//! `lon,lat,floor` (the API's examples). Degrees with 9 decimals (0.1 mm), metres with 3; a
//! floor not yet known is left empty.

use anyhow::{Context, Result, bail};
use std::path::PathBuf;
use std::time::Duration;
use wipdr_core::GeoFrame;
use wipdr_positioning::site_model::SiteModel;
use wipdr_positioning::{PositionEstimate, StreamSpec, samples_of};

/// `wipdr evaal` arguments.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The EvAAL API's root, e.g. `http://127.0.0.1:5000/evaalapi` (the trial name and the
    /// request are appended).
    #[arg(long)]
    pub server: String,
    /// The trial's name.
    #[arg(long)]
    pub trial: String,
    /// The site model (`wipdr fit`).
    #[arg(long)]
    pub model: PathBuf,
    /// Fusion scheme (`pdr` needs a known start and is refused).
    #[arg(long, default_value = "pmf")]
    pub scheme: String,
    /// How the position is written: `lon`, `lat`, `floor`, `x`, `y` joined by `,` or `;`.
    #[arg(long, default_value = "lon,lat,floor")]
    pub position_format: String,
    /// Seconds of data asked for with each request (the API's default).
    #[arg(long, default_value_t = 0.5)]
    pub horizon: f64,
    /// The stream's id, mixed into the scheme's seed (default: the trial name; `wipdr locate`
    /// uses the input file's name without extensions).
    #[arg(long)]
    pub stream_id: Option<String>,
    /// Reload the trial first (testing trials only: a scoring trial refuses).
    #[arg(long)]
    pub reload: bool,
    /// Also write every posted estimate as `request,t_ms,position` (the request that posted
    /// it, counted from 1; the time of the step or fix the estimate is from; the string).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// One field of a position string.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Field {
    Lon,
    Lat,
    Floor,
    X,
    Y,
}

/// A parsed `--position-format`: fields and the separators between them.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PositionFormat {
    fields: Vec<Field>,
    separators: Vec<char>,
}

impl PositionFormat {
    /// Parses `lon,lat,floor`-like formats; errors name the bad field.
    pub fn parse(text: &str) -> Result<Self> {
        let mut fields = Vec::new();
        let mut separators = Vec::new();
        let mut word = String::new();
        let push = |word: &mut String, fields: &mut Vec<Field>| -> Result<()> {
            let f = match word.trim() {
                "lon" => Field::Lon,
                "lat" => Field::Lat,
                "floor" => Field::Floor,
                "x" => Field::X,
                "y" => Field::Y,
                other => bail!(
                    "--position-format {text:?}: unknown field {other:?} (lon, lat, floor, x, y joined by ',' or ';')"
                ),
            };
            fields.push(f);
            word.clear();
            Ok(())
        };
        for c in text.chars() {
            if c == ',' || c == ';' {
                push(&mut word, &mut fields)?;
                separators.push(c);
            } else {
                word.push(c);
            }
        }
        push(&mut word, &mut fields)?;
        Ok(Self { fields, separators })
    }

    /// Whether the format has a floor field.
    pub fn has_floor(&self) -> bool {
        self.fields.contains(&Field::Floor)
    }

    /// Whether the format needs the model's WGS84 frame.
    pub fn needs_frame(&self) -> bool {
        self.fields
            .iter()
            .any(|f| matches!(f, Field::Lon | Field::Lat))
    }

    /// The position string of `e` (`frame` required when [`Self::needs_frame`]).
    pub fn format(&self, e: &PositionEstimate, frame: Option<&GeoFrame>) -> String {
        let (lat, lon) = frame.map_or((f64::NAN, f64::NAN), |f| f.to_lat_lon(e.position));
        let mut out = String::new();
        for (i, f) in self.fields.iter().enumerate() {
            if i > 0 {
                out.push(self.separators[i - 1]);
            }
            match f {
                Field::Lon => out.push_str(&format!("{lon:.9}")),
                Field::Lat => out.push_str(&format!("{lat:.9}")),
                Field::X => out.push_str(&format!("{:.3}", e.position.x)),
                Field::Y => out.push_str(&format!("{:.3}", e.position.y)),
                Field::Floor => {
                    if let Some(floor) = e.floor {
                        out.push_str(&floor.to_string());
                    }
                }
            }
        }
        out
    }
}

/// Record types whose third field is a SensorTimestamp (set to the AppTimestamp).
const SENSOR_TYPES: [&str; 5] = ["ACCE", "GYRO", "MAGN", "AHRS", "PRES"];

/// A logfile fragment with every sensor line on the AppTimestamp clock (its SensorTimestamp
/// field replaced by its AppTimestamp); other lines as they are.
pub fn on_app_clock(text: &str) -> String {
    let mut out = String::with_capacity(text.len() + 64);
    for line in text.lines() {
        let mut fields: Vec<&str> = line.split(';').collect();
        if fields.len() > 2 && SENSOR_TYPES.contains(&fields[0].trim()) {
            fields[2] = fields[1];
            out.push_str(&fields.join(";"));
        } else {
            out.push_str(line);
        }
        out.push('\n');
    }
    out
}

fn url(args: &Args, request: &str) -> String {
    format!(
        "{}/{}/{request}",
        args.server.trim_end_matches('/'),
        args.trial
    )
}

/// Runs `wipdr evaal`.
pub fn run(args: Args) -> Result<()> {
    if !(args.horizon.is_finite() && args.horizon > 0.0) {
        bail!(
            "--horizon {}: give a positive number of seconds",
            args.horizon
        );
    }
    let format = PositionFormat::parse(&args.position_format)?;
    let model = SiteModel::load(&args.model)?;
    let frame = model.data().geo_frame;
    if format.needs_frame() && frame.is_none() {
        bail!(
            "--position-format {}: the model {} has no WGS84 frame for lon/lat (use x,y)",
            args.position_format,
            args.model.display()
        );
    }
    let scheme = model.scheme(&args.scheme)?;
    if scheme.name() == "pdr" {
        bail!(
            "--scheme {}: dead reckoning needs a known start, which a trial does not give",
            args.scheme
        );
    }
    let stream_id = args.stream_id.clone().unwrap_or_else(|| args.trial.clone());
    let mut positioner = model.positioner(
        &args.scheme,
        &StreamSpec {
            id: Some(stream_id),
            identity: None,
            start: None,
        },
    )?;
    let agent: ureq::Agent = ureq::Agent::config_builder()
        .timeout_global(Some(Duration::from_secs(60)))
        .http_status_as_error(false)
        .build()
        .into();
    let get = |url: &str, query: &[(&str, String)]| -> Result<(u16, String)> {
        let mut request = agent.get(url);
        for (k, v) in query {
            request = request.query(*k, v);
        }
        let mut response = request.call().with_context(|| format!("GET {url}"))?;
        let status = response.status().as_u16();
        let body = response
            .body_mut()
            .with_config()
            .limit(1 << 30)
            .read_to_string()
            .with_context(|| format!("GET {url}: reading the answer"))?;
        Ok((status, body))
    };
    if args.reload {
        let (status, body) = get(&url(&args, "reload"), &[])?;
        if status != 200 {
            bail!("reload: HTTP {status}: {}", body.trim());
        }
    }
    let (status, state) = get(&url(&args, "state"), &[])?;
    if status != 200 {
        bail!("trial {}: HTTP {status}: {}", args.trial, state.trim());
    }
    tracing::info!(trial = %args.trial, state = %state.trim(), "trial state");
    let limits = wipdr_io::Limits::default();
    let horizon = format!("{}", args.horizon);
    let nextdata = url(&args, "nextdata");
    let mut posted: Vec<String> = Vec::new();
    let mut latest: Option<PositionEstimate> = None;
    let has_floor = format.has_floor();
    let (mut requests, mut lines, mut samples) = (0usize, 0usize, 0usize);
    let final_state = loop {
        let mut query = vec![("horizon", horizon.clone())];
        let position = latest
            .as_ref()
            .filter(|e| requests > 0 && (e.floor.is_some() || !has_floor))
            .map(|e| (e.t, format.format(e, frame.as_ref())));
        if let Some((_, p)) = &position {
            query.push(("position", p.clone()));
        }
        let (status, body) = get(&nextdata, &query)?;
        requests += 1;
        if !matches!(status, 200 | 405) {
            bail!("nextdata: HTTP {status}: {}", body.trim());
        }
        // The request that finds the trial finished (405) still sets its estimate.
        if let Some((t, p)) = position {
            posted.push(format!("{requests},{t},{p}"));
        }
        if status == 405 {
            break body;
        }
        if body.trim().is_empty() {
            continue;
        }
        lines += body.lines().count();
        let fragment = on_app_clock(&body);
        let log = wipdr_io::logfile::read_logfile_from(fragment.as_bytes(), &args.trial, &limits)
            .with_context(|| format!("reading the data of request {requests}"))?;
        for s in samples_of(&log.walk) {
            samples += 1;
            if let Some(mut e) = positioner.push(&s) {
                e.t = s.t();
                latest = Some(e);
            }
        }
    };
    eprintln!(
        "trial {}: {requests} requests, {lines} lines ({samples} samples), {} estimates posted; final state {}",
        args.trial,
        posted.len(),
        final_state.trim()
    );
    if let Some(out) = &args.out {
        let mut text = String::from("request,t_ms,position\n");
        for p in &posted {
            text.push_str(p);
            text.push('\n');
        }
        std::fs::write(out, text).with_context(|| format!("writing {}", out.display()))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use wipdr_core::Point2;

    #[test]
    fn position_formats_follow_the_trial() {
        let frame = GeoFrame::new(49.46, 11.11).unwrap();
        let e = PositionEstimate {
            t: 0,
            position: Point2::new(0.0, 0.0),
            floor: Some(-2),
            covariance: None,
        };
        let f = PositionFormat::parse("lon,lat,floor").unwrap();
        assert_eq!(f.format(&e, Some(&frame)), "11.110000000,49.460000000,-2");
        let g = PositionFormat::parse("x;y;floor").unwrap();
        assert!(!g.needs_frame());
        let unknown = PositionEstimate { floor: None, ..e };
        assert_eq!(g.format(&unknown, None), "0.000;0.000;");
        assert!(PositionFormat::parse("lon,height").is_err());
    }

    #[test]
    fn sensor_lines_move_onto_the_app_clock() {
        let text =
            "ACCE;0.015;17287.341;-2.6;8.6;2.7;3\nWIFI;0.5;17287.8;n;20:23:00:00:00:01;2437;-60\n";
        assert_eq!(
            on_app_clock(text),
            "ACCE;0.015;0.015;-2.6;8.6;2.7;3\nWIFI;0.5;17287.8;n;20:23:00:00:00:01;2437;-60\n"
        );
    }
}
