"""The report's figures, drawn with matplotlib (Agg: no display) from the accumulators' numbers and
written as PNG files."""

import math

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

DPI = 100
COLOURS = ("tab:blue", "tab:orange")


def save(fig, path):
    fig.savefig(path, dpi=DPI)
    plt.close(fig)


def histograms(hists, path, columns=3):
    """A panel per Histogram: its central 99 % in coarse bins, log x where it spans decades."""
    rows = math.ceil(len(hists) / columns)
    fig, axes = plt.subplots(rows, columns, figsize=(4.2 * columns, 3.0 * rows), layout="constrained", squeeze=False)
    for ax, h in zip(axes.flat, hists):
        shown = h.display(bins=int(np.clip(2 * math.sqrt(h.n), 10, 60)))
        ax.set_xlabel(h.label)
        if shown is None:
            ax.text(0.5, 0.5, "no finite values", ha="center", va="center", transform=ax.transAxes)
            continue
        edges, counts, outside = shown
        ax.stairs(counts, edges, fill=True, alpha=0.6, color=COLOURS[0])
        if h.asinh_scale is not None and edges[0] > 0 and edges[-1] / edges[0] > 20:
            ax.set_xscale("log")
        elif h.asinh_scale is not None and edges[0] < 0 < edges[-1] and edges[-1] - edges[0] > 20 * h.asinh_scale:
            ax.set_xscale("asinh", linear_width=h.asinh_scale)  # the bins' own scale: equal widths
        ax.set_ylabel("objects")
        if outside:
            ax.text(0.98, 0.95, f"{outside} outside", ha="right", va="top", fontsize=8, transform=ax.transAxes)
    for ax in axes.flat[len(hists):]:
        ax.set_visible(False)
    save(fig, path)


def points(ax, x, y, err, **style):
    """Points with error bars; a point whose error could not be computed (NaN: one ring pair or one
    object in its bin) is drawn hollow without a bar, not handed to errorbar as NaN (which warns)."""
    shown = np.isfinite(x) & np.isfinite(y)
    known = shown & np.isfinite(err)
    ax.errorbar(x[known], y[known], yerr=err[known], **style)
    if (shown & ~known).any():
        ax.plot(x[shown & ~known], y[shown & ~known], linestyle="none", marker="o", mfc="none", color=style["color"],
                ms=style["ms"])


def leakage(binned, lines, labels, path):
    """<e_i> against the PSF's e_i per component, the fitted line where the PSF's e varies."""
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.6), layout="constrained")
    for c, ax in enumerate(axes):
        rows = binned[c]
        if rows:
            x, y, err, _ = np.array(rows).T
            points(ax, x, y, err, fmt="o", color=COLOURS[c], ms=4, capsize=2)
            fit = lines[c]
            if math.isfinite(fit["alpha"]):
                xs = np.linspace(x.min(), x.max(), 2)
                ax.plot(xs, fit["intercept"] + fit["alpha"] * xs, "k-", lw=1,
                        label=f"α = {fit['alpha']:+.3g} ± {fit['alpha_err']:.2g}")
                ax.legend(fontsize=8)
            else:
                ax.text(0.5, 0.1, "one PSF e: α not measurable", ha="center", transform=ax.transAxes, fontsize=8)
        ax.axhline(0, color="0.7", lw=0.8)
        ax.set_xlabel(f"PSF {labels[c]}")
        ax.set_ylabel(f"⟨{labels[c]}⟩")
    save(fig, path)


def sky_maps(sky, path):
    """Object density and <e1>, <e2> of usable objects in cells of (ra, dec)."""
    fig, axes = plt.subplots(1, 3, figsize=(13, 4), layout="constrained")
    extent = (*sky.x_range, *sky.y_range)
    dec = 0.5 * (sky.y_range[0] + sky.y_range[1])
    cell = ((sky.x_range[1] - sky.x_range[0]) / sky.bins[0] * math.cos(math.radians(dec)) *
            (sky.y_range[1] - sky.y_range[0]) / sky.bins[1]) * 3600.0  # arcmin^2
    panels = [("objects / arcmin²", sky.counts / cell, "viridis", None)]
    for name in ("e1", "e2"):
        mean = sky.mean(name)
        limit = np.nanmax(np.abs(mean)) if np.isfinite(mean).any() else 1.0
        panels.append((f"⟨{name}⟩ (usable)", mean, "RdBu_r", (-limit, limit)))
    for ax, (title, values, cmap, limits) in zip(axes, panels):
        im = ax.imshow(values.T, origin="lower", extent=extent, aspect="auto", cmap=cmap,
                       vmin=None if limits is None else limits[0], vmax=None if limits is None else limits[1],
                       interpolation="nearest")
        ax.invert_xaxis()  # east to the left, as on the sky
        ax.set_title(title, fontsize=10)
        ax.set_xlabel("ra [deg]")
        ax.set_ylabel("dec [deg]")
        fig.colorbar(im, ax=ax, shrink=0.85)
    save(fig, path)


def e_against_truth(hist2d, binned, path):
    """Fitted e against the true (sheared) e per component: density, binned mean, y = x."""
    fig, axes = plt.subplots(1, 2, figsize=(9, 4.2), layout="constrained")
    for c, ax in enumerate(axes):
        h = hist2d[c]
        counts = np.where(h.counts > 0, h.counts, np.nan)
        ax.imshow(counts.T, origin="lower", extent=(*h.x_range, *h.y_range), cmap="Greys", aspect="equal",
                  interpolation="nearest", norm=matplotlib.colors.LogNorm() if h.counts.max() > 10 else None)
        rows = binned[c].display(bins=12, min_count=2)
        if rows:
            x, y, err, _ = np.array(rows).T
            points(ax, x, y, err, fmt="o", ms=3, color=COLOURS[c], label="binned mean")
        ax.plot([-1, 1], [-1, 1], "r-", lw=0.8, label="e = e_true")
        limit = 0.8
        ax.set_xlim(-limit, limit)
        ax.set_ylim(-limit, limit)
        ax.set_xlabel(f"e{c + 1}_obs (truth: intrinsic, sheared)")
        ax.set_ylabel(f"e{c + 1} fitted")
        ax.legend(fontsize=8, loc="upper left")
    save(fig, path)


def binned_biases(groups, path):
    """m and c per component in bins of S/N and of size, with their errors."""
    fig, axes = plt.subplots(2, len(groups), figsize=(3.6 * len(groups), 5.6), layout="constrained", squeeze=False)
    for g, (label, centres, values) in enumerate(groups):
        for row, quantity in enumerate(("m", "c")):
            ax = axes[row, g]
            for c in (0, 1):
                key = f"{quantity}{c + 1}"
                pts = [(x, v[key], v[key + "_err"]) for x, v in zip(centres, values) if v is not None]
                if pts:
                    x, y, err = np.array(pts).T
                    points(ax, x * (1 + 0.02 * (c - 0.5)), y, err, fmt="o", ms=4, capsize=2, color=COLOURS[c],
                           label=key)
            ax.axhline(0, color="0.7", lw=0.8)
            if min(centres) > 0 and max(centres) / min(centres) > 10:
                ax.set_xscale("log")
            ax.set_xlabel(label)
            ax.set_ylabel(quantity)
            if ax.get_legend_handles_labels()[0]:
                ax.legend(fontsize=8)
            else:
                ax.text(0.5, 0.5, "fewer than two sets with objects in any bin", ha="center", va="center",
                        fontsize=8, transform=ax.transAxes)
    save(fig, path)


def mosaic(stamps, path, per_row=2):
    """Data, model and residual per object, `per_row` objects to a row, worst first; data and
    model share a scale, the residual is symmetric about 0."""
    rows = math.ceil(len(stamps) / per_row)
    fig, axes = plt.subplots(rows, 3 * per_row, figsize=(2.0 * 3 * per_row, 2.1 * rows), layout="constrained",
                             squeeze=False)
    for ax in axes.flat:
        ax.set_visible(False)
    for k, (title, (data, model, resid)) in enumerate(stamps):
        row, first = divmod(k, per_row)
        lo, hi = np.nanmin(model), np.nanmax(data)
        limit = np.nanmax(np.abs(resid)) or 1.0
        for col, (image, kind) in enumerate(((data, "data"), (model, "model"), (resid, "residual"))):
            ax = axes[row, 3 * first + col]
            ax.set_visible(True)
            if col < 2:
                ax.imshow(image, origin="lower", cmap="viridis", vmin=lo, vmax=hi, interpolation="nearest")
            else:
                im = ax.imshow(image, origin="lower", cmap="RdBu_r", vmin=-limit, vmax=limit, interpolation="nearest")
                fig.colorbar(im, ax=ax, shrink=0.8)
            ax.set_xticks([])
            ax.set_yticks([])
            ax.set_title(f"{title}: {kind}" if col == 0 else kind, fontsize=8)
    save(fig, path)


def status_bars(names, counts, path):
    fig, ax = plt.subplots(figsize=(5, 2.6), layout="constrained")
    ax.barh(names, counts, color=COLOURS[0])
    if max(counts) > 100 * max(1, min(counts)):  # rare statuses stay visible beside the common one
        ax.set_xscale("symlog", linthresh=1)
    ax.invert_yaxis()
    ax.set_xlabel("objects")
    save(fig, path)


def metadetect_cuts(snr, t_ratio, cut_snr, cut_t_ratio, per_cell, flag_bars, path):
    """Metadetection: the S/N and T_ratio of the noshear detections with the cuts drawn, the
    detections per cell, and the detections per flag bit."""
    fig, axes = plt.subplots(2, 2, figsize=(9, 6), layout="constrained")
    for ax, h, cut in ((axes[0, 0], snr, cut_snr), (axes[0, 1], t_ratio, cut_t_ratio)):
        ax.set_xlabel(h.label)
        shown = h.display(bins=int(np.clip(2 * math.sqrt(h.n), 10, 60)))
        if shown is None:
            ax.text(0.5, 0.5, "no finite values", ha="center", va="center", transform=ax.transAxes)
            continue
        edges, counts, outside = shown
        ax.stairs(counts, edges, fill=True, alpha=0.6, color=COLOURS[0])
        if edges[0] > 0 and edges[-1] / edges[0] > 20:
            ax.set_xscale("log")
        ax.axvline(cut, color="tab:red", lw=1.2, label=f"cut: > {cut:g}")
        ax.set_ylabel("detections")
        ax.legend(fontsize=8, loc="upper right")
        if outside:
            ax.text(0.98, 0.80, f"{outside} outside", ha="right", va="top", fontsize=8, transform=ax.transAxes)
    ax = axes[1, 0]
    if per_cell.size:
        lo, hi = per_cell.min(), per_cell.max()
        ax.hist(per_cell, bins=np.arange(lo - 0.5, hi + 1.5, max(1, math.ceil((hi - lo + 1) / 40))),
                color=COLOURS[0], alpha=0.6)
        ax.set_xlim(min(lo - 2.5, 0.5 * (lo + hi) - 5), max(hi + 2.5, 0.5 * (lo + hi) + 5))  # whole numbers
    ax.xaxis.set_major_locator(matplotlib.ticker.MaxNLocator(integer=True))
    ax.set_xlabel("noshear detections per cell")
    ax.set_ylabel("cells")
    ax = axes[1, 1]
    if flag_bars:
        ax.barh([b[0] for b in flag_bars], [b[1] for b in flag_bars], color=COLOURS[1])
        ax.invert_yaxis()
    else:
        ax.text(0.5, 0.5, "no flags set", ha="center", va="center", transform=ax.transAxes)
        ax.set_xticks([])
        ax.set_yticks([])
    ax.set_xlabel("detections with the flag (all shear types)")
    save(fig, path)


def metadetect_response(means, labels, types, responses, step, path):
    """Metadetection: per shear type ⟨e_i⟩ of the kept rows minus noshear's, per table, with the
    ±step × R the sheared types should show."""
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.6), layout="constrained")
    x = np.arange(len(types))
    for c, ax in enumerate(axes):
        for k, (mean, label) in enumerate(zip(means, labels)):
            y = mean[:, c] - mean[0, c]
            shown = np.isfinite(y)
            ax.plot(x[shown] + 0.08 * (k - 0.5 * (len(means) - 1)), y[shown], "o", ms=6, color=COLOURS[k % 2],
                    label=f"{label} table".strip())
            r = responses[k][c]
            if math.isfinite(r):
                for sign, at in ((1, 1 + 2 * c), (-1, 2 + 2 * c)):
                    ax.plot([at - 0.3, at + 0.3], [sign * step * r] * 2, "--", color=COLOURS[k % 2], lw=1)
        ax.axhline(0, color="0.7", lw=0.8)
        ax.set_xticks(x, types)
        ax.set_ylabel(f"⟨e{c + 1}⟩ − ⟨e{c + 1}⟩ noshear")
        ax.set_title(f"e{c + 1}: {'1p, 1m' if c == 0 else '2p, 2m'} at ±MCSTEP × R{c + 1}{c + 1} (dashes)",
                     fontsize=9)
        if len(means) > 1:
            ax.legend(fontsize=8)
    save(fig, path)
