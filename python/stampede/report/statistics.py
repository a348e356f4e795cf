"""Streaming accumulators: each takes a table in chunks and keeps a fixed amount of state, so the
report's memory does not grow with the number of rows.

Histograms accumulate counts in fine fixed bins (linear for ellipticities, on asinh(x) for
quantities spanning decades); the plotted range (central 99 %) and its coarser bins are chosen from
those counts at the end, so one pass over the rows suffices.
"""

import math

import numpy as np

import stampede

# Rows whose e may enter a shear estimate: status ok and none of the engine's excluding flags (at
# bound, no errors, not converged, edge, PSF failure, metacal failure, ...), as `stampede metrics`.
SHEAR_EXCLUDING_FLAGS = stampede.shear_excluding_flags


def usable_for_shear(status, flags, e1, e2):
    return (status == 0) & ((flags & SHEAR_EXCLUDING_FLAGS) == 0) & np.isfinite(e1) & np.isfinite(e2)


class Histogram:
    """Counts in fine fixed bins of t = x (linear) or t = asinh(x / scale) (log-like both ways),
    with NaN, below- and above-range counts and exact moments, min and max."""

    def __init__(self, label, lo, hi, bins, asinh_scale=None, integer=False):
        self.label, self.lo, self.hi, self.bins = label, lo, hi, bins
        self.asinh_scale, self.integer = asinh_scale, integer
        self.counts = np.zeros(bins + 2, dtype=np.int64)  # [below, bins..., above]
        self.nan = 0
        # The moments are sums of x / scale and (x / scale)^2, scale the largest |x| so far (rescaled
        # when it grows): no overflow for any finite x (a flux of 1e162 squares to beyond the
        # largest double).
        self.total = self.sum = self.sum2 = 0.0
        self.scale = 0.0
        self.min, self.max = math.inf, -math.inf

    def forward(self, x):
        return x if self.asinh_scale is None else np.arcsinh(x / self.asinh_scale)

    def inverse(self, t):
        return t if self.asinh_scale is None else np.sinh(t) * self.asinh_scale

    def add(self, x):
        x = np.asarray(x, dtype=np.float64)
        finite = np.isfinite(x)
        self.nan += int(x.size - finite.sum())
        x = x[finite]
        if x.size == 0:
            return
        self.total += x.size
        scale = max(self.scale, float(np.abs(x).max()))
        if scale > self.scale:
            if self.scale > 0:
                ratio = self.scale / scale
                self.sum *= ratio
                self.sum2 *= ratio * ratio
            self.scale = scale
        if self.scale > 0:
            y = x / self.scale
            self.sum += float(y.sum())
            self.sum2 += float(np.dot(y, y))
        self.min, self.max = min(self.min, float(x.min())), max(self.max, float(x.max()))
        with np.errstate(over="ignore"):  # x near 1e308 in a linear histogram: t is inf, clipped to "above"
            t = (self.forward(x) - self.lo) * (self.bins / (self.hi - self.lo))
        index = np.clip(np.floor(t), -1, self.bins).astype(np.int64) + 1
        self.counts += np.bincount(index, minlength=self.bins + 2)

    @property
    def n(self):
        return int(self.total)

    def mean(self):
        return self.scale * (self.sum / self.total) if self.total else math.nan

    def std(self):
        if self.total < 2:
            return math.nan
        m = self.sum / self.total
        return self.scale * math.sqrt(max(0.0, self.sum2 / self.total - m * m))

    def fine_edges(self):
        return np.linspace(self.lo, self.hi, self.bins + 1)

    def quantile(self, q):
        """The q-quantile to within a fine bin (interpolated linearly in t inside it); values
        beyond the fine range are represented by min and max."""
        if not self.total:
            return math.nan
        cum = np.cumsum(self.counts)
        target = q * self.total
        k = int(np.searchsorted(cum, target, side="left"))
        if k == 0:
            return self.min
        if k == self.bins + 1:
            return self.max
        before = cum[k - 1]
        frac = (target - before) / max(1, self.counts[k])
        t = self.lo + (k - 1 + frac) * (self.hi - self.lo) / self.bins
        return float(np.clip(self.inverse(t), self.min, self.max))

    def display(self, bins=60, lo_q=0.005, hi_q=0.995):
        """(edges in x, counts, outside): coarse bins over the central quantile range, each a
        whole number of fine bins; `outside` counts the finite values left out."""
        if not self.total:
            return None
        lo, hi = self.quantile(lo_q), self.quantile(hi_q)
        if self.integer:
            lo, hi = math.floor(lo) - 0.5, math.ceil(hi) + 0.5
        t_lo, t_hi = float(self.forward(lo)), float(self.forward(hi))
        width = (self.hi - self.lo) / self.bins
        # In fine bins, held to the range first: (t - lo) / width is infinite for x near 1e308.
        def fine(t):
            return min(max((t - self.lo) / width, -1.0), self.bins + 1.0)

        first = int(np.clip(math.floor(fine(t_lo)), 0, self.bins - 1))
        last = int(np.clip(math.ceil(fine(t_hi)), first + 1, self.bins))
        step = max(1, int(math.ceil((last - first) / bins)))
        last = min(self.bins, first + step * int(math.ceil((last - first) / step)))
        inner = self.counts[1 + first:1 + last]
        if inner.size % step:
            inner = np.concatenate([inner, np.zeros(step - inner.size % step, dtype=inner.dtype)])
        counts = inner.reshape(-1, step).sum(axis=1)
        t_edges = self.lo + width * (first + step * np.arange(counts.size + 1))
        outside = int(self.total - counts.sum())
        return self.inverse(t_edges), counts, outside

    def summary(self):
        """The numbers printed beside the histogram."""
        return {"objects": self.n, "not finite": self.nan, "mean": self.mean(), "std": self.std(),
                "min": self.min if self.total else math.nan, "5%": self.quantile(0.05),
                "median": self.quantile(0.5), "95%": self.quantile(0.95),
                "max": self.max if self.total else math.nan}


class BinnedMean:
    """y against x: fine linear bins of x holding n, sum x, sum y, sum y^2, plus the global sums a
    least-squares line y = a + alpha x needs, so the slope and its error come from every row."""

    def __init__(self, lo, hi, bins):
        self.lo, self.hi, self.bins = lo, hi, bins
        self.n = np.zeros(bins, dtype=np.float64)
        self.sx = np.zeros(bins)
        self.sy = np.zeros(bins)
        self.syy = np.zeros(bins)
        self.total = self.shift_x = self.shift_y = None
        self.sums = np.zeros(6)  # n, x, y, xx, xy, yy of (x - shift_x, y - shift_y)

    def add(self, x, y):
        keep = np.isfinite(x) & np.isfinite(y)
        x, y = x[keep], y[keep]
        if x.size == 0:
            return
        if self.shift_x is None:  # sums about a typical point: no cancellation in the variances
            self.shift_x, self.shift_y = float(x[0]), float(y[0])
        # Values near 1e308 (a damaged table) overflow the sums to inf, which the page shows as such.
        with np.errstate(over="ignore", invalid="ignore"):
            dx, dy = x - self.shift_x, y - self.shift_y
            self.sums += [x.size, dx.sum(), dy.sum(), np.dot(dx, dx), np.dot(dx, dy), np.dot(dy, dy)]
            index = np.clip(np.floor((x - self.lo) * (self.bins / (self.hi - self.lo))), 0, self.bins - 1).astype(np.int64)
            self.n += np.bincount(index, minlength=self.bins)
            self.sx += np.bincount(index, weights=x, minlength=self.bins)
            self.sy += np.bincount(index, weights=y, minlength=self.bins)
            self.syy += np.bincount(index, weights=y * y, minlength=self.bins)

    def line(self):
        """{'n', 'alpha', 'alpha_err', 'intercept', 'intercept_err', 'x_spread'}; alpha NaN when x
        does not vary (one PSF for the whole table). Errors treat the rows as independent."""
        n, sx, sy, sxx, sxy, syy = map(float, self.sums)  # Python floats: sums of 1e308s give inf, not warnings
        out = {"n": int(n), "alpha": math.nan, "alpha_err": math.nan, "intercept": math.nan,
               "intercept_err": math.nan, "x_spread": math.nan}
        if n < 3:
            return out
        mx, my = sx / n, sy / n
        vxx, vxy, vyy = sxx / n - mx * mx, sxy / n - mx * my, syy / n - my * my
        out["x_spread"] = math.sqrt(max(0.0, vxx))
        if not vxx > 1e-12 * max(1.0, (mx + self.shift_x) * (mx + self.shift_x)):  # * not **: inf, no OverflowError
            return out
        alpha = vxy / vxx
        residual = max(0.0, (vyy - alpha * vxy) * n / (n - 2))
        mean_x = mx + self.shift_x
        out["alpha"], out["alpha_err"] = alpha, math.sqrt(residual / (n * vxx))
        out["intercept"] = my + self.shift_y - alpha * mean_x
        out["intercept_err"] = math.sqrt(residual * (1.0 / n + mean_x * mean_x / (n * vxx)))
        return out

    def display(self, bins=10, min_count=1):
        """Coarse bins of about equal population: rows of (x mean, y mean, y error, n)."""
        total = self.n.sum()
        if total == 0:
            return []
        cum = np.cumsum(self.n)
        cuts = np.searchsorted(cum, total * np.arange(1, bins) / bins, side="left") + 1
        groups = np.split(np.arange(self.bins), np.unique(cuts))
        rows = []
        for g in groups:
            with np.errstate(over="ignore", invalid="ignore"):  # sums of e near 1e308 are inf, shown as such
                sx, sy, syy = float(self.sx[g].sum()), float(self.sy[g].sum()), float(self.syy[g].sum())
            n = float(self.n[g].sum())
            if n < min_count:
                continue
            y = sy / n
            var = max(0.0, syy / n - y * y)
            rows.append((sx / n, y, math.sqrt(var / n) if n > 1 else math.nan, int(n)))
        return rows


class Histogram2D:
    """Counts in fixed bins of (x, y) over a box, e.g. e against e_true, or the sky."""

    def __init__(self, x_range, y_range, bins):
        self.x_range, self.y_range, self.bins = x_range, y_range, bins
        self.counts = np.zeros(bins, dtype=np.float64)
        self.weights = {}

    def add(self, x, y, **weights):
        keep = np.isfinite(x) & np.isfinite(y)
        for w in weights.values():
            keep &= np.isfinite(w)
        x, y = x[keep], y[keep]
        with np.errstate(over="ignore"):  # held to one cell outside, so that x near 1e308 casts
            ix = np.clip(np.floor((x - self.x_range[0]) / (self.x_range[1] - self.x_range[0]) * self.bins[0]),
                         -1, self.bins[0]).astype(np.int64)
            iy = np.clip(np.floor((y - self.y_range[0]) / (self.y_range[1] - self.y_range[0]) * self.bins[1]),
                         -1, self.bins[1]).astype(np.int64)
        inside = (ix >= 0) & (ix < self.bins[0]) & (iy >= 0) & (iy < self.bins[1])
        flat = (ix * self.bins[1] + iy)[inside]
        size = self.bins[0] * self.bins[1]
        self.counts += np.bincount(flat, minlength=size).reshape(self.bins)
        for name, w in weights.items():
            acc = self.weights.setdefault(name, np.zeros(self.bins))
            acc += np.bincount(flat, weights=w[keep][inside], minlength=size).reshape(self.bins)

    def mean(self, name):
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(self.counts > 0, self.weights[name] / self.counts, np.nan)

    def x_edges(self):
        return np.linspace(*self.x_range, self.bins[0] + 1)

    def y_edges(self):
        return np.linspace(*self.y_range, self.bins[1] + 1)


class StatusCounts:
    """Rows per status value and per flag bit, time per object, usable rows."""

    def __init__(self):
        self.status = {}
        self.flag_bits = np.zeros(32, dtype=np.int64)
        self.rows = self.usable = 0
        self.time_sum = 0.0
        self.time_rows = 0

    def add(self, status, flags, usable, time_us):
        self.rows += status.size
        self.usable += int(usable.sum())
        values, counts = np.unique(status, return_counts=True)
        for v, c in zip(values.tolist(), counts.tolist()):
            self.status[v] = self.status.get(v, 0) + c
        # Few distinct flag words occur: count those, then split each into its bits.
        words, counts = np.unique(flags, return_counts=True)
        self.flag_bits += (((words[:, None] >> np.arange(32, dtype=np.int64)) & 1) * counts[:, None]).sum(axis=0)
        finite = np.isfinite(time_us)
        self.time_sum += float(time_us[finite].sum())
        self.time_rows += int(finite.sum())
