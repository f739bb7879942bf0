"""wipdr: indoor positioning by Wi-Fi fingerprinting fused with pedestrian dead reckoning.

The Rust library (https://example.invalid/wipdr) as a Python package: numpy arrays in and
out, every computation in Rust.

- :func:`read_walk`, :func:`read_floor`: ILC 2.0 traces and floors, IPIN logfiles and
  folders of them, into :class:`Walk` and :class:`Floor` objects (or build them from your
  own arrays).
- :func:`evaluate`: the evaluation protocol of ``wipdr eval``; returns the document
  ``wipdr eval --json`` writes.
- :class:`SiteModel`: a site learned once from walks or survey records, saved and loaded
  (the file ``wipdr fit`` writes); :class:`Positioner`: position a stream on it one sample at
  a time; :func:`locate`: one walk as ``wipdr locate`` does. ``RadioMap`` is the former name
  of :class:`SiteModel` (``RadioMap.from_walks`` = :meth:`SiteModel.fit`), kept as an alias.
- Errors: :class:`WipdrError` and its subclasses (:mod:`wipdr.errors`).
"""

from wipdr.errors import ConfigError, DataError, InputError, WipdrError
from wipdr._wipdr import (
    SCHEMES,
    Estimate,
    Floor,
    FloorPlan,
    Positioner,
    SiteModel,
    Walk,
    evaluate,
    locate,
    read_floor,
    read_walk,
)

#: The former name of :class:`SiteModel`.
RadioMap = SiteModel

__all__ = [
    "SCHEMES",
    "ConfigError",
    "DataError",
    "Estimate",
    "Floor",
    "FloorPlan",
    "InputError",
    "Positioner",
    "RadioMap",
    "SiteModel",
    "Walk",
    "WipdrError",
    "evaluate",
    "locate",
    "read_floor",
    "read_walk",
]
