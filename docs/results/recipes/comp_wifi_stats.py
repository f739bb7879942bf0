"""Tables of docs/results/wifi-stats.md: `wipdr wifi-stats` on the five ILC floors."""

from regenerate import ilc_floors, table

from comp_common import row


def stats(runs, *args):
    return runs.wipdr_json("wifi-stats", "--data", *ilc_floors(), *args)


def groups(runs, *args):
    d = stats(runs, *args)
    return d["floors"] + [d["pooled"]]


def minus(x, digits=2):
    return f"{x:.{digits}f}".replace("-", "−")


def fit_cells(fit):
    """eta0, a, RSSI_r, c, r, rmse of one fit, with the bound the fit ended on named."""
    m, b = fit["model"], fit["at_bound"]
    eta0 = f"{m['eta0']:.2f}" + (" (bound)" if b["floor"] else "")
    end = "ceiling" if m["a"] > 0 else "eta0 + a ="
    a = minus(m["a"]) + (f" ({end} {m['eta0'] + m['a']:.0f}, bound)" if b["ceiling"] else "")
    rssi = minus(m["rssi_r"]) + (" (bound)" if b["rssi_r"] else "")
    c = f"{m['c']:.2f}" + (" (bound)" if b["c"] else "")
    return [eta0, a, rssi, c, f"{fit['correlation']:.3f}", f"{fit['rmse']:.1f}"]


def label(g):
    return f"**{g['label']}**" if g["label"] == "pooled" else g["label"]


@table("wifi-rr-points")
def rr_points(runs):
    """The refresh-rate model fitted to the (AP, walk) points, per floor and pooled."""
    out = ["| floor | walks | pairs | mean RR % | mean LR % | eta0 % | a % | RSSI_r dBm | c dB | r | rmse % |",
           "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for g in groups(runs):
        cells = fit_cells(g["refresh_fit"])
        if g["label"] == "pooled":
            cells[2] = f"**{cells[2]}**"
        out.append(row(label(g), g["walks"], f"{g['pairs']:,}", f"{g['mean_refresh_pct']:.1f}",
                       f"{g['mean_loss_pct']:.1f}", *cells))
    return "\n".join(out)


@table("wifi-rr-bins")
def rr_bins(runs):
    """The refresh-rate model fitted to the 1 dB binned means, per floor and pooled."""
    out = ["| floor | eta0 % | a % | RSSI_r dBm | c dB | r | rmse % |",
           "| --- | --- | --- | --- | --- | --- | --- |"]
    for g in groups(runs):
        cells = fit_cells(g["refresh_fit_binned"])
        if g["label"] == "pooled":
            cells[2] = f"**{cells[2]}**"
        out.append(row(label(g), *cells))
    return "\n".join(out)


@table("wifi-lr-fits")
def lr_fits(runs):
    """The loss-rate fits (same model, a < 0): binned means and (AP, walk) points."""
    out = ["| floor | binned: eta0 % | a % | RSSI_r dBm | c dB | r | rmse % | points: r |",
           "| --- | --- | --- | --- | --- | --- | --- | --- |"]
    for g in groups(runs):
        out.append(row(label(g), *fit_cells(g["loss_fit_binned"]),
                       f"{g['loss_fit']['correlation']:.3f}"))
    return "\n".join(out)


@table("wifi-robustness")
def robustness(runs):
    """Pooled figures with one option of the command changed."""
    out = ["| run | pooled mean RR % | RSSI_r, points fit (dBm) | RSSI_r, binned fit (dBm) |",
           "| --- | --- | --- | --- |"]
    for name, args in [("the command above (tolerance 200 ms, span >= 5 scans)", ()),
                       ("`--refresh-tolerance-ms 0`", ("--refresh-tolerance-ms", "0")),
                       ("`--refresh-tolerance-ms 1000`", ("--refresh-tolerance-ms", "1000")),
                       ("`--min-span-scans 10`", ("--min-span-scans", "10"))]:
        p = stats(runs, *args)["pooled"]
        out.append(row(name, f"{p['mean_refresh_pct']:.1f}",
                       minus(p["refresh_fit"]["model"]["rssi_r"]),
                       minus(p["refresh_fit_binned"]["model"]["rssi_r"])))
    return "\n".join(out)
