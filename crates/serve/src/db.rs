//! The database: sessions and their estimates in SQLite (WAL), written in batched
//! transactions.
//!
//! Writes are queued in memory ([`Db::queue`]) and written by [`Db::flush`], one transaction
//! for everything queued, which the server calls every flush interval, before it reads a
//! track and when it stops. A `kill -9` therefore loses at most what was queued since the last
//! flush: one flush interval. With WAL and `synchronous = NORMAL` a committed transaction
//! survives the death of the process; a power cut may lose the last transactions too (SQLite's
//! documented trade-off; `synchronous = FULL` would sync every commit).
//!
//! Tables: `sessions(id, owner, scheme, device, stream_id, created_unix_ms, closed_unix_ms,
//! close_reason)` and `estimates(session, seq, t_ms, x, y, floor, sd_m)` (`REAL` is an IEEE
//! double: the stored estimates are the served ones bit for bit).

use crate::auth::Owner;
use crate::errors::ServeError;
use rusqlite::{Connection, OptionalExtension, params};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// One estimate of a track, as served and stored.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct StoredEstimate {
    /// Time of the sample that made it, ms on the stream's clock.
    pub t_ms: i64,
    /// Easting in the model's metre frame.
    pub x: f64,
    /// Northing in the model's metre frame.
    pub y: f64,
    /// Floor, where known.
    pub floor: Option<i32>,
    /// Horizontal standard deviation, metres, where the scheme has one.
    pub sd_m: Option<f64>,
}

impl StoredEstimate {
    /// The estimate as the track formats write it
    /// ([`wipdr_positioning::track_format`], shared with `wipdr locate`).
    pub fn row(&self) -> wipdr_positioning::track_format::TrackRow {
        wipdr_positioning::track_format::TrackRow {
            t_ms: self.t_ms,
            x: self.x,
            y: self.y,
            floor: self.floor,
            sd_m: self.sd_m,
        }
    }
}

/// A session's metadata, as stored.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SessionRecord {
    /// The session id.
    pub id: String,
    /// The owner (SHA-256 of its token).
    #[serde(skip)]
    pub owner: Owner,
    /// The scheme it runs.
    pub scheme: String,
    /// The device label its client gave.
    pub device: String,
    /// The stream id (seed of the stream).
    pub stream_id: String,
    /// When it was created, Unix ms.
    pub created_unix_ms: i64,
    /// When it was closed, Unix ms (`None` while open).
    pub closed_unix_ms: Option<i64>,
    /// Why it was closed (`client`, `idle`, `shutdown`, `restart`).
    pub close_reason: Option<String>,
    /// Time of its last sample, where it was closed by this server (not after a kill).
    pub last_sample_t_ms: Option<i64>,
}

/// A queued write.
#[derive(Debug, Clone, PartialEq)]
pub enum Write {
    /// A new session.
    Session(SessionRecord),
    /// The next estimates of a session (`first_seq` numbers the first).
    Estimates {
        /// The session.
        session: String,
        /// Sequence number of the first.
        first_seq: i64,
        /// The estimates.
        estimates: Vec<StoredEstimate>,
    },
    /// A session closed.
    Closed {
        /// The session.
        session: String,
        /// When, Unix ms.
        at_unix_ms: i64,
        /// Why.
        reason: String,
        /// Time of its last sample (the IPIN rows run to it).
        last_sample_t_ms: Option<i64>,
    },
}

/// The database: a connection and the queue of writes not yet flushed.
#[derive(Debug)]
pub struct Db {
    path: PathBuf,
    conn: Mutex<Connection>,
    queue: Mutex<Vec<Write>>,
}

const SCHEMA: &str = "
CREATE TABLE IF NOT EXISTS sessions (
    id TEXT PRIMARY KEY,
    owner TEXT NOT NULL,
    scheme TEXT NOT NULL,
    device TEXT NOT NULL,
    stream_id TEXT NOT NULL,
    created_unix_ms INTEGER NOT NULL,
    closed_unix_ms INTEGER,
    close_reason TEXT,
    last_sample_t_ms INTEGER
);
CREATE TABLE IF NOT EXISTS estimates (
    session TEXT NOT NULL,
    seq INTEGER NOT NULL,
    t_ms INTEGER NOT NULL,
    x REAL NOT NULL,
    y REAL NOT NULL,
    floor INTEGER,
    sd_m REAL,
    PRIMARY KEY (session, seq)
) WITHOUT ROWID;
";

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    // A panic while holding the lock cannot leave these structures half-written in a way
    // that matters (a queue, a connection): go on with them.
    m.lock().unwrap_or_else(|p| p.into_inner())
}

impl Db {
    /// Opens (or creates) the database at `path` in WAL mode, and closes every session a
    /// previous run left open (reason `restart`): their tracks stay readable.
    pub fn open(path: &Path, now_unix_ms: i64) -> Result<Self, ServeError> {
        let err = |source| ServeError::Database {
            path: path.to_path_buf(),
            source,
        };
        let conn = Connection::open(path).map_err(err)?;
        conn.pragma_update(None, "journal_mode", "WAL")
            .map_err(err)?;
        conn.pragma_update(None, "synchronous", "NORMAL")
            .map_err(err)?;
        conn.busy_timeout(std::time::Duration::from_secs(5))
            .map_err(err)?;
        conn.execute_batch(SCHEMA).map_err(err)?;
        conn.execute(
            "UPDATE sessions SET closed_unix_ms = ?1, close_reason = 'restart' WHERE closed_unix_ms IS NULL",
            params![now_unix_ms],
        )
        .map_err(err)?;
        Ok(Self {
            path: path.to_path_buf(),
            conn: Mutex::new(conn),
            queue: Mutex::new(Vec::new()),
        })
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Queues a write for the next [`Db::flush`].
    pub fn queue(&self, w: Write) {
        lock(&self.queue).push(w);
    }

    /// Writes everything queued in one transaction; returns how many writes it held. On an
    /// error the writes are put back at the front of the queue (the next flush retries).
    pub fn flush(&self) -> Result<usize, ServeError> {
        let writes = std::mem::take(&mut *lock(&self.queue));
        if writes.is_empty() {
            return Ok(0);
        }
        let n = writes.len();
        let mut conn = lock(&self.conn);
        match write_all(&mut conn, &writes) {
            Ok(()) => Ok(n),
            Err(source) => {
                let mut q = lock(&self.queue);
                let later = std::mem::replace(&mut *q, writes);
                q.extend(later);
                Err(ServeError::Database {
                    path: self.path.clone(),
                    source,
                })
            }
        }
    }

    /// A stored session.
    pub fn session(&self, id: &str) -> Result<Option<SessionRecord>, ServeError> {
        let conn = lock(&self.conn);
        conn.query_row(
            "SELECT id, owner, scheme, device, stream_id, created_unix_ms, closed_unix_ms, close_reason, last_sample_t_ms FROM sessions WHERE id = ?1",
            params![id],
            |r| {
                let owner: String = r.get(1)?;
                Ok(SessionRecord {
                    id: r.get(0)?,
                    // A row of another format's owner matches no token.
                    owner: Owner::from_hex(&owner).unwrap_or(Owner([0; 32])),
                    scheme: r.get(2)?,
                    device: r.get(3)?,
                    stream_id: r.get(4)?,
                    created_unix_ms: r.get(5)?,
                    closed_unix_ms: r.get(6)?,
                    close_reason: r.get(7)?,
                    last_sample_t_ms: r.get(8)?,
                })
            },
        )
        .optional()
        .map_err(|source| ServeError::Database {
            path: self.path.clone(),
            source,
        })
    }

    /// A session's stored track, in order.
    pub fn track(&self, id: &str) -> Result<Vec<StoredEstimate>, ServeError> {
        let conn = lock(&self.conn);
        let err = |source| ServeError::Database {
            path: self.path.clone(),
            source,
        };
        let mut stmt = conn
            .prepare_cached(
                "SELECT t_ms, x, y, floor, sd_m FROM estimates WHERE session = ?1 ORDER BY seq",
            )
            .map_err(err)?;
        let rows = stmt
            .query_map(params![id], |r| {
                Ok(StoredEstimate {
                    t_ms: r.get(0)?,
                    x: r.get(1)?,
                    y: r.get(2)?,
                    floor: r.get(3)?,
                    sd_m: r.get(4)?,
                })
            })
            .map_err(err)?;
        rows.collect::<Result<Vec<_>, _>>().map_err(err)
    }
}

fn write_all(conn: &mut Connection, writes: &[Write]) -> rusqlite::Result<()> {
    let tx = conn.transaction()?;
    {
        let mut add_session = tx.prepare_cached(
            "INSERT OR IGNORE INTO sessions (id, owner, scheme, device, stream_id, created_unix_ms) VALUES (?1, ?2, ?3, ?4, ?5, ?6)",
        )?;
        let mut add_estimate = tx.prepare_cached(
            "INSERT OR REPLACE INTO estimates (session, seq, t_ms, x, y, floor, sd_m) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7)",
        )?;
        let mut close = tx.prepare_cached(
            "UPDATE sessions SET closed_unix_ms = ?2, close_reason = ?3, last_sample_t_ms = ?4 WHERE id = ?1 AND closed_unix_ms IS NULL",
        )?;
        for w in writes {
            match w {
                Write::Session(s) => {
                    add_session.execute(params![
                        s.id,
                        s.owner.hex(),
                        s.scheme,
                        s.device,
                        s.stream_id,
                        s.created_unix_ms
                    ])?;
                }
                Write::Estimates {
                    session,
                    first_seq,
                    estimates,
                } => {
                    for (k, e) in estimates.iter().enumerate() {
                        add_estimate.execute(params![
                            session,
                            first_seq + k as i64,
                            e.t_ms,
                            e.x,
                            e.y,
                            e.floor,
                            e.sd_m
                        ])?;
                    }
                }
                Write::Closed {
                    session,
                    at_unix_ms,
                    reason,
                    last_sample_t_ms,
                } => {
                    close.execute(params![session, at_unix_ms, reason, last_sample_t_ms])?;
                }
            }
        }
    }
    tx.commit()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(id: &str) -> SessionRecord {
        SessionRecord {
            id: id.into(),
            owner: Owner([7; 32]),
            scheme: "ekf".into(),
            device: "Pixel 7 \"<b>\"".into(),
            stream_id: id.into(),
            created_unix_ms: 1,
            closed_unix_ms: None,
            close_reason: None,
            last_sample_t_ms: None,
        }
    }

    #[test]
    fn tracks_survive_reopening_bit_for_bit_and_open_sessions_close_as_restarted() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("t.sqlite");
        let track = vec![
            StoredEstimate {
                t_ms: 10,
                x: 0.1 + 0.2,
                y: -1e-300,
                floor: Some(-1),
                sd_m: None,
            },
            StoredEstimate {
                t_ms: 20,
                x: f64::MAX,
                y: 3.0,
                floor: None,
                sd_m: Some(std::f64::consts::PI),
            },
        ];
        {
            let db = Db::open(&p, 0).unwrap();
            db.queue(Write::Session(record("s1")));
            db.queue(Write::Estimates {
                session: "s1".into(),
                first_seq: 0,
                estimates: track.clone(),
            });
            assert_eq!(db.flush().unwrap(), 2);
            // Queued but never flushed: lost, as a kill -9 would lose it.
            db.queue(Write::Session(record("s2")));
        }
        let db = Db::open(&p, 99).unwrap();
        assert_eq!(db.track("s1").unwrap(), track);
        let s = db.session("s1").unwrap().unwrap();
        assert_eq!(s.owner, Owner([7; 32]));
        assert_eq!(s.device, "Pixel 7 \"<b>\"");
        assert_eq!(s.closed_unix_ms, Some(99));
        assert_eq!(s.close_reason.as_deref(), Some("restart"));
        assert!(db.session("s2").unwrap().is_none());
    }
}
