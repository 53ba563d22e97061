"""Report figures (matplotlib, Agg), each returned as PNG bytes. Units on every axis."""

from __future__ import annotations

import io

import numpy as np


def _plt():
    # local: matplotlib is slow to import (and its backend must be set before pyplot is)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _png(fig) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    _plt().close(fig)
    return buf.getvalue()


def _marks(report: dict):
    m = report["marks"]
    ids = [i for i in m if m[i].get("status", "ok") == "ok"]   # unreliable: not fitted
    xy = np.array([m[i]["measured_mm"] for i in ids], float).reshape(-1, 2)
    rb = np.array([m[i].get("residual_base_mm", m[i]["residual_mm"]) for i in ids],
                  float).reshape(-1, 2)
    rf = np.array([m[i]["residual_mm"] for i in ids], float).reshape(-1, 2)
    q = np.array([m[i].get("joints_deg", [np.nan, np.nan]) for i in ids], float).reshape(-1, 2)
    s = np.array([m[i].get("approach", [1, 1]) for i in ids], float).reshape(-1, 2)
    roles = [m[i].get("role", "calibration") for i in ids]
    return ids, xy, rb, rf, q, s, roles


def residual_field(report: dict) -> bytes:
    """Residual arrows on the sheet, base model and final model, each panel at its own
    scale (its longest arrow draws 60 mm, said in its title: the final model's arrows are
    tens of times shorter and would look empty at the base model's scale); the axes hold
    every arrow's tip.

    Fitted marks red, held-out marks blue. The RMS in the titles is calibration.json's
    (``residual_rms_mm``, ``validation_rms_mm``), never recomputed here: the figure and the
    tables show the same number."""
    plt = _plt()
    ids, xy, rb, rf, _, _, roles = _marks(report)
    held = np.array([r == "validation" for r in roles], dtype=bool)
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.8), layout="constrained", sharex=True,
                             sharey=True)
    fit_rms, val_rms = report.get("residual_rms_mm", {}), report.get("validation_rms_mm", {})
    tips = [xy]
    for ax, r, key, title in ((axes[0], rb, "base_model", "base model"),
                              (axes[1], rf, "final_model", "final model")):
        big = max(float(np.nanmax(np.hypot(*r.T))) if len(r) else 0.0, 1e-6)
        scale = big / 60.0  # the longest arrow of this panel draws 60 mm long
        tips.append(xy + r / scale)
        for k, color, lab in ((~held, "tab:red", "fitted"), (held, "tab:blue", "held out")):
            if k.any():
                ax.quiver(xy[k, 0], xy[k, 1], r[k, 0], r[k, 1], angles="xy", scale_units="xy",
                          scale=scale, color=color, width=0.004, label=lab)
        ax.plot(xy[:, 0], xy[:, 1], "k.", ms=3)
        t = f"{title}: fitted RMS {_mm(fit_rms.get(key))}"
        if val_rms.get(key) is not None:
            t += f", held-out {_mm(val_rms.get(key))}"
        ax.set_title(t + f"\narrows x{1 / scale:.0f} ({big:.3f} mm draws 60 mm)", fontsize=10)
        ax.set_xlabel("sheet x [mm]")
        ax.set_aspect("equal")
        ax.grid(alpha=0.3)
        if held.any():
            ax.legend(fontsize=8)
    axes[0].set_ylabel("sheet y [mm]")
    t = np.vstack(tips)
    t = t[np.all(np.isfinite(t), axis=1)]
    if len(t):
        pad = 10.0
        axes[0].set_xlim(t[:, 0].min() - pad, t[:, 0].max() + pad)
        axes[0].set_ylim(t[:, 1].min() - pad, t[:, 1].max() + pad)
    fig.suptitle("residual field (each panel at its own scale)")
    return _png(fig)


def _mm(x) -> str:
    """One formatting for RMS figures, shared with the report's tables."""
    return "-" if x is None or not np.isfinite(x) else f"{x:.4f} mm"


def joint_residuals(report: dict) -> bytes:
    """Residuals as joint-angle errors against each joint angle, split by approach: the
    marks' ``residual_base_joint_deg`` / ``residual_joint_deg`` (calibration.json, computed
    by the pipeline: :mod:`vision_cal.estimate.report_data`)."""
    plt = _plt()
    m = report["marks"]
    ids, xy, rb, rf, q, s, _ = _marks(report)
    fig, axes = plt.subplots(2, 2, figsize=(11, 6.5), layout="constrained")
    for row, (key, title) in enumerate((("residual_base_joint_deg", "base model"),
                                        ("residual_joint_deg", "final model"))):
        dq = np.array([m[i].get(key) or [np.nan, np.nan] for i in ids],
                      float).reshape(-1, 2) * 1000.0
        for j in range(2):
            ax = axes[row, j]
            for sign, color, lab in ((1, "tab:blue", "approach +"), (-1, "tab:orange",
                                                                     "approach -")):
                k = s[:, j] == sign
                ax.plot(q[k, j], dq[k, j], "o", ms=4, color=color, label=lab)
            ax.axhline(0, color="k", lw=0.6)
            ax.set_xlabel(f"joint {j + 1} command [deg]")
            ax.set_ylabel(f"joint {j + 1} residual [mdeg]")
            ax.set_title(f"{title}: joint {j + 1}")
            ax.grid(alpha=0.3)
            ax.legend(fontsize=8)
    return _png(fig)


def circles(report: dict) -> bytes | None:
    """The paper-style circle fits with the marks on them."""
    c = report.get("circles")
    if not c:
        return None
    plt = _plt()
    ids, xy, *_ = _marks(report)
    fig, ax = plt.subplots(figsize=(6, 5.5), layout="constrained")
    t = np.linspace(0, 2 * np.pi, 400)
    for key, color in (("base", "tab:blue"), ("elbow", "tab:green")):
        cc = c[key]
        cx, cy = cc["center_mm"]
        r = cc["radius_mm"]
        ax.plot(cx + r * np.cos(t), cy + r * np.sin(t), color=color, lw=0.8,
                label=f"{key} circle r {r:.2f} mm, arc {cc['arc_span_deg']:.0f} deg")
        ax.plot([cx], [cy], "+", color=color, ms=10)
    ax.plot(xy[:, 0], xy[:, 1], "k.", ms=5, label="marks")
    ax.set_aspect("equal")
    ax.set_xlabel("sheet x [mm]")
    ax.set_ylabel("sheet y [mm]")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    return _png(fig)


def targets(report: dict) -> bytes | None:
    """Table-3 errors of every target, before and after, as bars."""
    t = report.get("loop", {}).get("targets")
    if not t:
        return None
    plt = _plt()
    ids = [r["id"] for r in t]
    before = [r.get("before_error_mm") or np.nan for r in t]
    after = [r.get("after_error_mm") or np.nan for r in t]
    fig, ax = plt.subplots(figsize=(11, 4), layout="constrained")
    x = np.arange(len(ids))
    ax.bar(x - 0.2, before, 0.4, label="nominal model (before)")
    ax.bar(x + 0.2, after, 0.4, label="calibrated model (after)")
    ax.set_yscale("log")
    # a target with no value (not planned, not measured: the table says why) is marked
    # on the axis instead of leaving a silent gap
    lo = np.nanmin([v for v in before + after if v > 0] or [1e-3]) / 3
    for off, vals, color in ((-0.2, before, "tab:blue"), (0.2, after, "tab:orange")):
        miss = [i for i, v in enumerate(vals) if not np.isfinite(v)]
        if miss:
            ax.plot(x[miss] + off, np.full(len(miss), lo), "x", color=color, ms=7, mew=2,
                    label="no value (see the table)" if color == "tab:blue" else None)
    ax.set_xticks(x, ids, rotation=90, fontsize=7)
    ax.set_ylabel("absolute error [mm]")
    # above the axes: inside, the legend hid the first targets' bars
    ax.legend(loc="lower left", bbox_to_anchor=(0.0, 1.01), ncols=3, fontsize=9,
              frameon=False)
    ax.grid(alpha=0.3, axis="y")
    return _png(fig)


def sheet_height(report: dict) -> bytes | None:
    """The sheet's height map (sheet_height, with its marks) and the marks' local-versus-
    global differences (measured against the printed grid minus the marker mapping, arrows):
    None when the calibration has neither."""
    m = report.get("marks", {})
    lg = [(v["measured_mm"], v["local_minus_global_mm"]) for v in m.values()
          if v.get("local_minus_global_mm") is not None]
    hm = (report.get("diagnosis") or {}).get("sheet_height")
    if not lg and not hm:
        return None
    plt = _plt()
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.6), layout="constrained", sharex=True,
                             sharey=True)
    ax = axes[0]
    if hm and hm.get("grid"):
        g = hm["grid"]
        z = np.asarray(g["z_mm"], float)
        lim = max(float(np.nanmax(np.abs(z))), 1e-3)
        im = ax.pcolormesh(g["x_mm"], g["y_mm"], z, cmap="RdBu_r", vmin=-lim, vmax=lim,
                           shading="nearest")
        fig.colorbar(im, ax=ax, label="height above the markers' plane [mm]")
        mk = hm.get("marks", {})
        if mk:
            p = np.array([v["xy_mm"] for v in mk.values()], float)
            ax.scatter(p[:, 0], p[:, 1], c=[v["height_mm"] for v in mk.values()], cmap="RdBu_r",
                       vmin=-lim, vmax=lim, edgecolors="k", s=22)
        sd = np.asarray(g.get("std_mm", [[np.nan]]), float)
        ax.set_title(f"sheet height ({'claimed' if hm.get('claimed') else 'not claimed'}; "
                     f"median std {np.nanmedian(sd):.3f} mm)")
    else:
        ax.set_title("sheet height: not observable (no grid, camera did not move)")
    ax = axes[1]
    if lg:
        xy = np.array([a for a, _ in lg], float)
        d = np.array([b for _, b in lg], float)
        big = max(float(np.max(np.hypot(*d.T))), 1e-6)
        ax.quiver(xy[:, 0], xy[:, 1], d[:, 0], d[:, 1], angles="xy", scale_units="xy",
                  scale=big / 40.0, color="tab:blue", width=0.004)
        ax.set_title(f"grid minus marker mapping (max {big:.3f} mm)")
    else:
        ax.set_title("no mark measured against the printed grid")
    for a in axes:
        a.set_xlabel("sheet x [mm]")
        a.set_aspect("equal")
        a.grid(alpha=0.3)
    axes[0].set_ylabel("sheet y [mm]")
    return _png(fig)


def print_deviation(ap: dict | None) -> bytes | None:
    """The sheet as printed (measurement.json ``as_printed``, #28): each marker outlined
    where the layout puts it, an arrow from every corner to where it was printed (scaled);
    None without it."""
    if not ap or not ap.get("markers"):
        return None
    dec = np.array([m["declared_mm"] for m in ap["markers"]], float).reshape(-1, 4, 2)
    got = np.array([m["corners_mm"] for m in ap["markers"]], float).reshape(-1, 4, 2)
    rel = np.array([m["released"] for m in ap["markers"]], bool).reshape(-1, 4)
    d = (got - dec)[rel]
    p = dec[rel]
    big = max(float(np.max(np.hypot(*d.T))) if len(d) else 0.0, 1e-6)
    span = float(np.ptp(dec.reshape(-1, 2), axis=0).max())
    k = 0.06 * span / big
    plt = _plt()
    fig, ax = plt.subplots(figsize=(8, 5.6), layout="constrained")
    for c in dec:
        ax.fill(c[:, 0], c[:, 1], fill=False, ec="0.6", lw=0.8)
    ax.quiver(p[:, 0], p[:, 1], d[:, 0], d[:, 1], angles="xy", scale_units="xy",
              scale=1.0 / k, color="tab:red", width=0.003)
    ax.set_title(f"print minus layout at the markers' corners: RMS {ap.get('rms_mm', 0):.3f} "
                 f"mm, max {big:.3f} mm (arrows x{k:.0f})")
    ax.set_xlabel("sheet x [mm]")
    ax.set_ylabel("sheet y [mm]")
    ax.set_aspect("equal")
    ax.grid(alpha=0.3)
    return _png(fig)


# ------------------------------------------------------------------- the closed loop

def loop_paths(loop: dict) -> bytes:
    """Targets and where the pen really went, before and after (paper Fig. 8-9), from
    loop.json."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(9, 6.5), layout="constrained")
    t = np.array([r["target_mm"] for r in loop["targets"]], float).reshape(-1, 2)
    ax.plot(t[:, 0], t[:, 1], "k+", ms=9, label="targets")
    for name, color in (("before", "tab:red"), ("after", "tab:green")):
        pts = np.array([r[name]["measured_mm"] for r in loop["targets"]
                        if "measured_mm" in r[name]], float).reshape(-1, 2)
        if len(pts):
            ax.plot(pts[:, 0], pts[:, 1], "o", mfc="none", color=color,
                    label=f"measured marks, {name} calibration")
    ax.set_aspect("equal")
    ax.set_xlabel("sheet x [mm]")
    ax.set_ylabel("sheet y [mm]")
    ax.legend(loc="lower left", bbox_to_anchor=(0.0, 1.06), ncols=3, fontsize=9,
              frameon=False)   # outside: inside it hid targets
    ax.grid(alpha=0.3)
    ax.set_title("targets and where the pen really went (paper Fig. 8-9)")
    return _png(fig)


def loop_joints(loop: dict) -> bytes:
    """Joint reference trajectories of the planned targets before and after (paper
    Fig. 10), from loop.json's ``trajectories`` (planned by the loop from ``home_deg``:
    :func:`vision_cal.actions.loop.loop_trajectories`)."""
    plt = _plt()
    fig, axes = plt.subplots(2, 1, figsize=(9, 6), layout="constrained", sharex=True)
    tr = loop.get("trajectories") or {}
    for name, style in (("before", "--"), ("after", "-")):
        if name not in tr:
            continue
        t = np.asarray(tr[name]["t_s"], float)
        q = np.asarray(tr[name]["q_deg"], float).reshape(-1, 2)
        for j in range(2):
            axes[j].plot(t, q[:, j], style, lw=1, label=f"{name} calibration")
    for j in range(2):
        axes[j].set_ylabel(f"joint {j + 1} reference [deg]")
        axes[j].grid(alpha=0.3)
        axes[j].legend()
    axes[1].set_xlabel(f"time [s] (samples every {tr.get('dt_s')} s)")
    axes[0].set_title("joint reference trajectories before and after (paper Fig. 10)")
    return _png(fig)
