//! What a [`crate::Positioner`] may know of the place: the floor plan's indexes (walls,
//! walkable raster), where the radio map has coverage, where training walks went.

use std::sync::Arc;
use wipdr_core::{FloorPlan, Point2};
use wipdr_fingerprint::RadioMap;
use wipdr_fingerprint::likelihood::ScanLikelihood;
use wipdr_fusion::{BuildContext, TrailRaster, WalkableGrid, WallIndex};

/// Raster cell of [`Site::walkable`], metres (`pmf`'s walkability and map matching).
pub const WALKABLE_CELL_M: f64 = 0.5;

/// The place a stream is positioned in, shared (cheaply cloned) by many streams.
#[derive(Debug, Clone, Default)]
pub struct Site {
    /// Wall index (wall-aware particle filters); `None` without a plan.
    pub walls: Option<Arc<WallIndex>>,
    /// Walkable-space raster; `None` when there is no plan or it has no outline.
    pub walkable: Option<Arc<WalkableGrid>>,
    /// Where the radio map has fingerprints (coverage-aware schemes: `pmf`).
    pub coverage: Option<Arc<Vec<Point2>>>,
    /// Where training walks went (`pmf`'s optional trail prior).
    pub trails: Option<Arc<TrailRaster>>,
    /// Each floor's AP signal fields: a scan's likelihood over the floor (`pmf` with
    /// `wifi_likelihood`); `None` when not fit.
    pub likelihood: Option<Arc<ScanLikelihood>>,
}

impl Site {
    /// A site from a floor plan (walls and walkable raster; a plan without an outline has no
    /// walkable raster) and the radio map's coverage.
    pub fn new(plan: Option<&FloorPlan>, map: &RadioMap) -> Self {
        let mut site = Self::from_plan(plan);
        site.coverage = Some(Arc::new(map.points().iter().map(|p| p.position).collect()));
        site
    }

    /// The plan's part of a site (no coverage, no trails).
    pub fn from_plan(plan: Option<&FloorPlan>) -> Self {
        let Some(plan) = plan else {
            tracing::warn!(
                "no floor plan: map matching, pmf's walkability and apf's walls are off for this site"
            );
            return Self::default();
        };
        let walkable = if plan.outline.is_empty() {
            if plan.walls.is_empty() {
                tracing::warn!(
                    "no floor plan: map matching, pmf's walkability and apf's walls are off for this site"
                );
            } else {
                tracing::warn!(
                    "the floor plan has no outline: map matching and pmf's walkability are off for this site"
                );
            }
            None
        } else {
            match WalkableGrid::new(plan, WALKABLE_CELL_M) {
                Ok(g) => Some(Arc::new(g)),
                Err(e) => {
                    tracing::warn!(error = %e, "no walkable raster for this plan");
                    None
                }
            }
        };
        Self {
            walls: Some(Arc::new(WallIndex::new(&plan.walls))),
            walkable,
            coverage: None,
            trails: None,
            likelihood: None,
        }
    }

    /// The fusion build context of one stream.
    pub fn build_context(&self, seed: u64, start: Option<Point2>) -> BuildContext {
        BuildContext {
            walls: self.walls.clone(),
            seed,
            start,
            walkable: self.walkable.clone(),
            coverage: self.coverage.clone(),
            trails: self.trails.clone(),
        }
    }
}

/// Mixes a base seed with a stream's id (FNV-1a), so every walk has its own random stream;
/// evaluation and `wipdr locate` seed each walk this way.
pub fn stream_seed(seed: u64, stream_id: &str) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325 ^ seed;
    for b in stream_id.bytes() {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}
