"""Streaming a recorded walk sample by sample from Python (no pytest needed: the
examples use it too)."""


def stream_order(walk):
    """A walk's samples in the one stream order of the Rust `samples_of`: by time, ties by
    kind (rotation vector, gyroscope, magnetometer, accelerometer, pressure, Wi-Fi), each
    sensor's own order kept."""
    items = []
    for rank, (kind, arr) in enumerate(
        [
            ("rotation_vector", walk.rotation_vector),
            ("gyroscope", walk.gyroscope),
            ("magnetometer", walk.magnetometer),
            ("accelerometer", walk.accelerometer),
            ("pressure", walk.pressure),
        ]
    ):
        for row in arr:
            items.append((int(row[0]), rank, kind, tuple(float(v) for v in row[1:])))
    for t, entries in walk.scans_with_times:
        items.append((t, 5, "scan", entries))
    items.sort(key=lambda s: (s[0], s[1]))
    return items


def push_all(positioner, walk):
    """Feeds a walk's samples to a Positioner one at a time; returns how many."""
    return push_items(positioner, stream_order(walk))


def push_items(positioner, items):
    """Feeds samples of :func:`stream_order` to a Positioner one at a time; returns how many."""
    push = {
        "rotation_vector": positioner.push_rotation_vector,
        "gyroscope": positioner.push_gyroscope,
        "magnetometer": positioner.push_magnetometer,
        "accelerometer": positioner.push_accelerometer,
    }
    n = 0
    for t, _, kind, payload in items:
        if kind == "scan":
            positioner.push_scan(t, payload)
        elif kind == "pressure":
            positioner.push_pressure(t, payload[0])
        else:
            push[kind](t, *payload)
        n += 1
    return n
