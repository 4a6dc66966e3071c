"""Per-node (or per-cell) ensemble statistics with confidence limits.

Reductions run along ``realization`` only, so a dask-backed ensemble (a run folder's
chunk files or a zarr store, ``uqdrape.ensemble.open_ensemble``) is processed chunk by
chunk, memory bounded by a few chunks whatever the ensemble's size: moments in one pass
of shifted power sums, quantiles and their limits as exact order statistics found by
narrowing histograms of integer keys in a few more passes (:func:`order_statistics`).
"""

from __future__ import annotations

from collections.abc import Sequence

import dask
import dask.array
import numpy as np
import xarray as xr
from dask.delayed import Delayed
from scipy import stats

from ._common import REALIZATION, check_confidence, get_variable, t_quantile

MEAN_INTERVAL = "Student t: mean +- t_{(1+c)/2, n-1} * sd / sqrt(n) over the n valid realisations"
#: The interval of the mean of a randomised QMC sample: its points are not independent,
#: its K randomisations are.
REPLICATE_INTERVAL = ("Student t over randomisations: mean of the K randomisations' means +- "
                      "t_{(1+c)/2, K-1} * sd(means) / sqrt(K)")
QUANTILE_INTERVAL = ("distribution-free order statistics: [X_(l), X_(u)] with l = binom.ppf((1-c)/2, n, p), "
                     "u = binom.ppf((1+c)/2, n, p) + 1 (1-based ranks, coverage >= c); NaN when n is too small")
QUANTILE_METHOD = "numpy 'linear' (Hyndman-Fan type 7) over the valid realisations"


def _attrs(units, long_name: str, **extra) -> dict:
    """``long_name``, ``units`` where given, and ``extra``."""
    return {"long_name": long_name, **({} if units is None else {"units": units}), **extra}


def _limits(prefix: str, lower, upper, units, what: str, confidence: float, method: str) -> dict:
    """``<prefix>_lower`` and ``<prefix>_upper``: the confidence limits of ``what`` with their attributes."""
    return {f"{prefix}_{side}": limit.assign_attrs(_attrs(units, f"{side} {confidence:.0%} confidence limit of {what}",
                                                          method=method))
            for side, limit in (("lower", lower), ("upper", upper))}


def moment_statistics(da: xr.DataArray, confidence: float, dim: str = REALIZATION) -> xr.Dataset:
    """Lazy mean, sd, skewness, count and t interval of the mean of ``da`` along ``dim``.

    NaN entries are invalid realisations and are left out. Values are shifted by the
    first realisation (per node) before the power sums, which keeps the one-pass
    variance accurate when the mean is large against the spread (e.g. coordinates in mm).
    sd uses ddof = 1; skewness is the adjusted Fisher-Pearson G1 (scipy ``bias=False``),
    NaN for n < 3 or zero spread.
    """
    units = da.attrs.get("units")
    name = da.attrs.get("long_name", da.name)
    valid = da.notnull()
    shift = da.isel({dim: 0}, drop=True).fillna(0.0)
    d = da - shift
    n = valid.sum(dim)
    nn = n.where(n > 0).astype(float)
    a1 = d.sum(dim) / nn
    a2 = (d**2).sum(dim) / nn
    a3 = (d**3).sum(dim) / nn
    m2 = (a2 - a1**2).clip(min=0.0)
    m3 = a3 - 3.0 * a1 * a2 + 2.0 * a1**3
    mean = shift + a1
    sd = np.sqrt((m2 * nn / (nn - 1.0)).where(n > 1))
    spread = (m2 > (np.finfo(float).resolution * mean) ** 2) & (n > 2)
    m2s = m2.where(spread)
    skew = (m3 / m2s**1.5 * np.sqrt(nn * (nn - 1.0)) / (nn - 2.0)).where(spread)
    half = t_quantile(confidence, n - 1) * sd / np.sqrt(nn)
    return xr.Dataset({
        "mean": mean.assign_attrs(_attrs(units, f"ensemble mean of {name}")),
        "sd": sd.assign_attrs(_attrs(units, f"ensemble standard deviation (ddof=1) of {name}")),
        "skewness": skew.assign_attrs(_attrs("1", f"adjusted sample skewness G1 of {name}")),
        "count": n.assign_attrs(_attrs("1", "number of valid (non-NaN) realisations")),
        **_limits("mean", mean - half, mean + half, units, "the mean", confidence, MEAN_INTERVAL)})


#: the sign bit of a float64, which orders the keys of :func:`_keys`
_SIGN = np.uint64(1 << 63)
#: a key range past every region (an unused region slot)
_NONE = np.uint64(2**64 - 1)


def _keys(x) -> np.ndarray:
    """Order-preserving uint64 keys of the values ``x`` as float64: a < b exactly when
    key(a) < key(b) (-0.0 is taken as 0.0; a NaN's key means nothing, mask it)."""
    u = (np.asarray(x, dtype=np.float64) + 0.0).view(np.uint64)
    return np.where(u & _SIGN, ~u, u | _SIGN)


def _from_keys(keys) -> np.ndarray:
    """The float64 values of :func:`_keys`."""
    keys = np.asarray(keys, dtype=np.uint64)
    return np.where(keys & _SIGN, keys & ~_SIGN, ~keys).view(np.float64)


def _bit_length(w: np.ndarray) -> np.ndarray:
    """Bits of the uint64 values ``w`` (0 for 0), exactly."""
    bits = np.zeros(w.shape, dtype=np.uint64)
    for k in (32, 16, 8, 4, 2, 1):
        big = w >= np.uint64(1 << k)
        bits += np.where(big, np.uint64(k), np.uint64(0))
        w = np.where(big, w >> np.uint64(k), w)
    return bits + (w > 0)


def _locate(x, base, lo, hi):
    """(node, slot, offset key) of each valid value of the block ``x`` (realisations
    first, then its nodes) that lies in a region of its node: slot s of node k holds
    the keys base[k] + lo[k, s] .. base[k] + hi[k, s], lo ascending along s (unused
    slots lo = 2**64 - 1)."""
    x = x.reshape(x.shape[0], -1)
    d = _keys(x) - base
    slot = np.full(d.shape, -1, dtype=np.intp)
    for s in range(lo.shape[1]):
        slot += d >= lo[:, s]
    rows, nodes = np.nonzero(~np.isnan(x) & (slot >= 0))
    slot, d = slot[rows, nodes], d[rows, nodes]
    inside = d <= hi[nodes, slot]
    return nodes[inside], slot[inside], d[inside]


def _histogram_block(x, base, lo, hi, shift, bins: int) -> np.ndarray:
    """Counts (node, slot, bin) of a block's values in each region, cut into ``bins``
    bins of 2**shift keys from its lower end."""
    nodes, slot, d = _locate(x, base, lo, hi)
    width = lo.shape[1] * bins
    at = nodes * width + slot * bins + ((d - lo[nodes, slot]) >> shift[nodes, slot]).astype(np.intp)
    counts = np.bincount(at, minlength=lo.shape[0] * width).astype(np.int32)  # < 2**31 realisations
    return counts.reshape(lo.shape[0], lo.shape[1], bins)


def _gather_block(x, base, lo, hi, node_ids) -> tuple[np.ndarray, np.ndarray]:
    """(region id = node id * slots + slot, offset key) of a block's values in the regions."""
    nodes, slot, d = _locate(x, base, lo, hi)
    return node_ids[nodes] * lo.shape[1] + slot, d


def _blocks(data) -> list:
    """(block, its node slices) of an array with realisations first: every dask block
    as a delayed object, a numpy array whole."""
    if not isinstance(data, dask.array.Array):
        return [(data, (slice(None),) * (data.ndim - 1))]
    edges = [np.cumsum((0, *c)) for c in data.chunks[1:]]
    blocks = data.to_delayed()
    return [(blocks[at], tuple(slice(e[k], e[k + 1]) for e, k in zip(edges, at[1:]))) for at in np.ndindex(blocks.shape)]


def _part(node_shape: tuple, a: np.ndarray, where: tuple) -> np.ndarray:
    """The rows of ``a`` (nodes flattened first) of the nodes ``where`` of ``node_shape``."""
    return a.reshape(node_shape + a.shape[1:])[where].reshape(-1, *a.shape[1:])


def _call(func, block, *args):
    """``func(block, *args)``, delayed if ``block`` is a dask block."""
    return dask.delayed(func)(block, *args) if isinstance(block, Delayed) else func(block, *args)


def _tree_sum(parts: list):
    """The sum of ``parts``, added in pairs (a few partial sums alive at once)."""
    while len(parts) > 1:
        parts = [_call(np.add, *parts[k:k + 2]) if k + 1 < len(parts) else parts[k] for k in range(0, len(parts), 2)]
    return parts[0]


def _regions(lo, hi, count, active):
    """The distinct regions of each node's active targets as slots, ascending: (slot lo,
    slot hi, slot count, each target's slot); unused slots lo = 2**64 - 1."""
    key = np.where(active, lo, _NONE)
    ordered = np.sort(key, axis=1)
    first = np.ones(ordered.shape, dtype=bool)
    first[:, 1:] = ordered[:, 1:] != ordered[:, :-1]
    first &= ordered != _NONE
    position = np.cumsum(first, axis=1) - 1
    slots = max(int(first.sum(axis=1).max()), 1)
    node = np.broadcast_to(np.arange(lo.shape[0])[:, None], lo.shape)
    slot_lo = np.full((lo.shape[0], slots), _NONE)
    slot_lo[node[first], position[first]] = ordered[first]
    of = np.count_nonzero(slot_lo[:, None, :] <= lo[:, :, None], axis=-1) - 1
    slot_hi = np.zeros_like(slot_lo)
    slot_count = np.zeros(slot_lo.shape, dtype=np.int64)
    slot_hi[node[active], of[active]] = hi[active]
    slot_count[node[active], of[active]] = count[active]
    return slot_lo, slot_hi, slot_count, of


def _pass_bytes() -> int:
    """Memory of one pass of :func:`order_statistics`: a quarter of dask's
    ``array.chunk-size`` (32 MiB by default)."""
    return dask.utils.parse_bytes(dask.config.get("array.chunk-size")) // 4


def _histograms(blocks, node_shape: tuple, base, slot_lo, slot_hi, shift, bins: int) -> np.ndarray:
    """One pass: the counts (node, slot, bin) of the values of every region, summed
    over the blocks of each block of nodes in pairs."""
    parts = {}
    for block, where in blocks:
        state = (_part(node_shape, a, where) for a in (base, slot_lo, slot_hi, shift))
        parts.setdefault(tuple((w.start, w.stop) for w in where), (where, []))[1].append(
            _call(_histogram_block, block, *state, bins))
    sums = dask.compute(*(_tree_sum(p) for _, p in parts.values()))
    hist = np.empty((*node_shape, slot_lo.shape[1], bins), dtype=np.int64)
    for (where, _), part in zip(parts.values(), sums):
        hist[where] = part.reshape(hist[where].shape)
    return hist.reshape(slot_lo.shape[0], slot_lo.shape[1], bins)


def _gathered(blocks, node_shape: tuple, base, slot_lo, slot_hi) -> tuple[np.ndarray, np.ndarray]:
    """One pass: (region ids, offset keys) of the values of every region, sorted."""
    ids = np.arange(slot_lo.shape[0])
    parts = dask.compute(*(_call(_gather_block, block, *(_part(node_shape, a, where) for a in (base, slot_lo, slot_hi, ids)))
                           for block, where in blocks))
    region = np.concatenate([p[0] for p in parts])
    keys = np.concatenate([p[1] for p in parts])
    order = np.lexsort((keys, region))
    return region[order], keys[order]


def order_statistics(data, n, low, high, ranks, need) -> np.ndarray:
    """Exact order statistics of ``data`` (realisations first, NaN invalid) along its
    first axis: element [..., t] is the ``ranks[..., t]``-th smallest (0-based) valid
    value of the node (NaN where ``need`` is False), as float64, with memory bounded by
    a few blocks of ``data`` (a dask array is read a block at a time) and a few passes.

    ``n``, ``low``, ``high``: each node's number of valid values, smallest and largest.
    Every value is mapped to an order-preserving integer key (:func:`_keys`) so that
    bins are exact. Each wanted rank lies in a region of keys of its node, at first
    [key(low), key(high)]; a pass counts the values of every region in up to 2**b bins
    (b such that the histograms take half of :func:`_pass_bytes`) and narrows each
    rank's region to its bin, until the values left in the regions fit in
    :func:`_pass_bytes` (16 bytes each): a last pass gathers them and sorts. A region of
    one key is the value itself (ties need no pass). Each pass shortens every region by
    b bits of 64 (4 <= b <= 16: 16 bins at least, whatever the histograms' memory), so
    passes are bounded, and an ensemble 2**b times larger needs about one more;
    an ensemble of smooth fields of 441 nodes needs one or two before the gathering
    pass (10^4 to 10^6 realisations, default ``array.chunk-size``)."""
    shape, node_shape = ranks.shape, ranks.shape[:-1]
    ranks, need = ranks.reshape(-1, shape[-1]), need.reshape(-1, shape[-1])
    base = _keys(np.where(np.isnan(low), 0.0, low)).reshape(-1)
    top = _keys(np.where(np.isnan(high), 0.0, high)).reshape(-1)
    lo = np.zeros(ranks.shape, dtype=np.uint64)  # each rank's region: keys base + lo .. base + hi
    hi = np.broadcast_to(np.where(top >= base, top - base, 0)[:, None], ranks.shape).copy()
    before = np.zeros(ranks.shape, dtype=np.int64)  # the node's values below the region
    count = np.broadcast_to(np.reshape(n, (-1, 1)), ranks.shape).astype(np.int64)  # and in it
    node = np.broadcast_to(np.arange(lo.shape[0])[:, None], lo.shape)
    blocks = _blocks(data)
    limit = _pass_bytes()
    while (active := need & (lo < hi)).any():
        slot_lo, slot_hi, slot_count, of = _regions(lo, hi, count, active)
        region = node[active] * slot_lo.shape[1] + of[active]
        if slot_count[slot_lo != _NONE].sum() * 16 <= limit:
            ids, keys = _gathered(blocks, node_shape, base, slot_lo, slot_hi)
            lo[active] = keys[np.searchsorted(ids, region) + ranks[active] - before[active]]
            break
        bits = int(np.clip(np.log2(limit / 16 / slot_lo.size), 4, 16))
        shift = np.where(slot_lo != _NONE, _bit_length(slot_hi - slot_lo), np.uint64(bits))
        shift = np.maximum(shift, np.uint64(bits)) - np.uint64(bits)  # bins of 2**shift keys
        hist = _histograms(blocks, node_shape, base, slot_lo, slot_hi, shift, 1 << bits).reshape(-1)
        total = np.cumsum(hist)  # one running total over every region's bins: search each rank's bin
        first = region << bits
        offset = np.where(first > 0, total[first - 1], 0)
        at = np.searchsorted(total, offset + ranks[active] - before[active], side="right")
        count[active] = hist[at]
        before[active] += total[at] - hist[at] - offset
        step = shift.reshape(-1)[region]
        start = lo[active] + ((at - first).astype(np.uint64) << step)
        lo[active] = start
        hi[active] = np.minimum(start + ((np.uint64(1) << step) - np.uint64(1)), hi[active])
    return np.where(need, _from_keys(base[:, None] + lo), np.nan).reshape(shape)


def _ranks(n: np.ndarray, probs: np.ndarray, confidence: float):
    """The order statistics behind the quantiles of nodes of ``n`` (..., 1) valid values:
    (ranks, need, virtual, below), ranks (..., 4 Q) 0-based: numpy's "linear" quantile
    interpolates at virtual rank (n-1) p between ranks floor and floor + 1 (the largest
    value at or past it), and its order-statistic limits are ranks l and u
    (QUANTILE_INTERVAL); need is False where a rank does not exist (n = 0, l < 1, u > n)."""
    virtual = (n - 1) * probs
    below = np.floor(virtual)
    top = virtual >= n - 1  # at or past the largest valid value: take it
    alpha = 1.0 - confidence
    with np.errstate(invalid="ignore"):
        lower = stats.binom.ppf(alpha / 2.0, n, probs)
        upper = stats.binom.ppf(1.0 - alpha / 2.0, n, probs) + 1.0
    some = np.broadcast_to(n > 0, virtual.shape)
    ok_lower, ok_upper = (lower >= 1) & some, (upper <= n) & some
    ranks = np.concatenate([np.where(top, n - 1, below), np.where(top, n - 1, below + 1),
                            np.where(ok_lower, lower - 1, 0), np.where(ok_upper, upper - 1, 0)], axis=-1)
    need = np.concatenate([some, some, ok_lower, ok_upper], axis=-1)
    return np.clip(ranks, 0, None).astype(np.int64), need, virtual, below


def quantile_statistics(da: xr.DataArray, quantiles: Sequence[float], confidence: float,
                        dim: str = REALIZATION, *, moments: bool = False) -> xr.Dataset:
    """Quantiles of ``da`` along ``dim`` with distribution-free confidence limits, computed.

    Quantiles are numpy's "linear" method of the valid (non-NaN) values, the same numbers
    as ``np.nanquantile`` in float64 (NaN for a node with none); their limits are order
    statistics. All are exact order statistics found by :func:`order_statistics`, with
    memory bounded by a few dask blocks of ``da``, not by the ensemble: a first pass
    over a dask-backed ``da`` counts each node's valid values and finds their range
    (with ``moments``, :func:`moment_statistics` is computed in that pass and merged into
    the result), then usually two or three more passes."""
    probs = np.asarray(quantiles, dtype=float)
    if probs.ndim != 1 or probs.size == 0 or np.any(~(probs > 0) | ~(probs < 1)):
        raise ValueError(f"quantiles must be a non-empty sequence of probabilities in (0, 1), got {quantiles!r}")
    rest = [d for d in da.dims if d != dim]
    first = xr.Dataset({"n": da.count(dim), "low": da.fillna(np.inf).min(dim), "high": da.fillna(-np.inf).max(dim)})
    if moments:
        first = xr.merge([moment_statistics(da, confidence, dim), first], combine_attrs="override")
    first = first.compute()
    n = first["n"].transpose(*rest).values[..., None]
    ranks, need, virtual, below = _ranks(n, probs, confidence)
    found = order_statistics(da.transpose(dim, *rest).data, n[..., 0], first["low"].transpose(*rest).values,
                             first["high"].transpose(*rest).values, ranks, need)
    a, b, lower, upper = np.split(found, 4, axis=-1)
    t = virtual - below
    with np.errstate(invalid="ignore"):  # inf - inf between infinite values, as in numpy
        diff = b - a
        value = np.where(n > 0, np.where(t >= 0.5, b - diff * (1 - t), a + diff * t), np.nan)
    units = da.attrs.get("units")
    name = da.attrs.get("long_name", da.name)
    coords = {k: c for k, c in da.coords.items() if dim not in c.dims}
    coords["quantile"] = ("quantile", probs, {"long_name": "probability level", "units": "1"})
    dims = (*rest, "quantile")
    out = xr.Dataset({
        "quantile_value": (dims, value, _attrs(units, f"ensemble quantile of {name}", method=QUANTILE_METHOD)),
        **{k: (dims, v.values, v.attrs) for k, v in _limits(
            "quantile", xr.DataArray(lower), xr.DataArray(upper), units, "the quantile", confidence,
            QUANTILE_INTERVAL).items()}}, coords=coords)
    return xr.merge([first.drop_vars(["n", "low", "high"]), out], combine_attrs="override") if moments else out


def mean_statistics(da: xr.DataArray, confidence: float = 0.95, dim: str = REALIZATION) -> xr.Dataset:
    """Mean, sd, skewness, count and Student-t interval of the mean of any DataArray.

    For per-realisation scalars (energies, line means, asymmetry) as well as fields.
    Returns the computed Dataset (variables ``mean, sd, skewness, count, mean_lower,
    mean_upper``) in the units of ``da``.
    """
    c = check_confidence(confidence)
    if dim not in da.dims:
        raise ValueError(f"dim={dim!r} is not a dim of the DataArray; dims: {da.dims}")
    return moment_statistics(da.astype(float), c, dim).assign_attrs(confidence=c).compute()


def node_statistics(ds: xr.Dataset, var: str = "shear", quantiles: Sequence[float] = (0.05, 0.5, 0.95),
                    confidence: float = 0.95, replicates: int | None = None) -> xr.Dataset:
    """Per-node (or per-cell, for a cell variable) ensemble statistics of ``ds[var]``.

    Reduces along ``realization``, keeping every other dim (i, j or cell_i, cell_j, and
    a leading ``blankholder_force``). Only valid (non-NaN) realisations count. Variables:
    ``mean, sd, skewness, count, mean_lower, mean_upper`` and, along dim ``quantile``,
    ``quantile_value, quantile_lower, quantile_upper``; units those of ``var``. The mean
    interval is Student t; quantile limits are distribution-free order statistics (see
    each variable's ``method`` attr). The moments are computed in the first pass of the
    quantiles' few passes (:func:`quantile_statistics`); returns in-memory data.
    ``replicates`` K: the realisations are K equal consecutive randomisations of one
    randomised-QMC point set (``[sampling] plan = "rqmc"``): the mean's interval is then
    Student t over the K randomisations' means (REPLICATE_INTERVAL), as the points within
    one are not independent; sd and quantiles stay those of all realisations.
    """
    c = check_confidence(confidence)
    da = get_variable(ds, var)
    out = quantile_statistics(da, quantiles, c, moments=True)
    if replicates is not None:
        out.update(_replicate_limits(da, int(replicates), c))
    out.attrs = {**ds.attrs, "variable": var, "confidence": c}
    return out.compute()


def _replicate_limits(da: xr.DataArray, replicates: int, confidence: float) -> dict:
    """The mean's limits from the spread of ``replicates`` consecutive groups' means."""
    n = da.sizes[REALIZATION]
    if replicates < 2 or n % replicates:
        raise ValueError(f"replicates={replicates} must be >= 2 and divide the {n} realisations")
    group = xr.DataArray(np.arange(n) // (n // replicates), dims=REALIZATION, name="randomization")
    means = da.groupby(group).mean(REALIZATION)  # a randomisation's mean over its valid points
    k = means.notnull().sum("randomization")
    half = t_quantile(confidence, k - 1) * means.std("randomization", ddof=1) / np.sqrt(k.where(k > 0))
    centre = means.mean("randomization")
    return _limits("mean", centre - half, centre + half, da.attrs.get("units"), "the mean", confidence,
                   REPLICATE_INTERVAL)


def ring_sd(ds: xr.Dataset, var: str = "shear") -> xr.DataArray:
    """Per-node ensemble sd of ``var`` (deg) averaged over each ring k = max(|i|, |j|) = 1..n.

    Rings are the net's distance from the crossover in segments; the result has dim
    ``ring`` (plus a leading ``blankholder_force`` of a sweep). Nodes with fewer than
    two valid realisations are left out of their ring's average.
    """
    sd = node_statistics(ds, var)["sd"]
    ring = np.maximum(abs(sd["i"]), abs(sd["j"]))
    n = int(ring.max())
    per_ring = [sd.where(ring == k).mean(("i", "j")) for k in range(1, n + 1)]
    out = xr.concat(per_ring, dim="ring").assign_coords(ring=np.arange(1, n + 1))
    return out.assign_attrs(units=sd.attrs.get("units", "degree"),
                            long_name=f"mean over the ring's nodes of the ensemble sd of {var}")


def inner_outer_sd(ds: xr.Dataset, var: str = "shear", band: int = 5) -> tuple[float, float]:
    """(inner, outer) ring-averaged sd of ``var`` (deg): rings 1..band and the ``band``
    rings just inside the boundary ring (n-band..n-1). The boundary ring is left out:
    its node shear averages fewer cells (one at a corner), which adds scatter of its own."""
    per_ring = ring_sd(ds, var)
    n = per_ring.sizes["ring"]
    if n < 2 * band + 1:
        raise ValueError(f"band={band} needs a net of at least {2 * band + 1} rings, got {n}")
    inner = float(per_ring.sel(ring=slice(1, band)).mean())
    outer = float(per_ring.sel(ring=slice(n - band, n - 1)).mean())
    return inner, outer
