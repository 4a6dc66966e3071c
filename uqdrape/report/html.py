"""``write_report``: the figures of an ensemble's report plan and one self-contained HTML page.

The page (``index.html``) uses inline CSS and relative links to PNGs in the same
folder, so the folder can be copied or served as is. Layout: title, provenance (date,
uqdrape version, git commit, wall time of the run), the headline table, a sensitivity
sample's indices, the figures two to a row (a wide figure spans the row), the study
file once and the ensemble's other attributes. ``summary.json`` holds the same numbers
(``uqdrape.stats.headline_numbers``) and the provenance.
"""

from __future__ import annotations

import html
import json
import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import xarray as xr

from uqdrape.schema import FORCE, QOI_ATTRS, REALIZATION, by_force
from uqdrape.stats import dominant_factors, headline_numbers, node_statistics, study_kind, wrinkle_risk
from uqdrape.stats.headline import SENSITIVITY, DETERMINISTIC, RANDOM, SWEPT

from ..experimental import read_experimental
from ..conventions import cf_encode
from ..files import write_atomic, write_text_atomic
from .page import figures_html, page, provenance, provenance_line
from .style import check_formats, vector_formats
from .plan import PLAN, SENSITIVITY_PLAN, Context, render
from .sensitivity_figures import INDICES

#: The node number along the max-shear lines the thesis shows histograms of (Fig 5.20).
THESIS_HISTOGRAM_NODE = 6
#: Attributes shown elsewhere on the page (the study file) or too long for the table.
_HIDDEN_ATTRS = ("study_toml", "study_json")
#: The per-node statistics file a report writes beside its page.
STATISTICS_FILE = "statistics.nc"
_KIND_TEXT = {
    RANDOM: "a random sample: every ensemble statistic applies",
    DETERMINISTIC: "one drape per blank-holder level: no spread statistics",
    SWEPT: "a deterministic sweep over one factor: results against the factor, no distribution fits",
    SENSITIVITY: "the rows of a sensitivity sample: indices first; no confidence intervals or convergence",
}


def default_histogram_nodes(ds: xr.Dataset, node_stats: xr.Dataset) -> list[tuple[int, int]]:
    """Node k of a + and a - quadrant max-shear line, (k, k) and (-k, k), k = min(6, rings) or less.

    k steps down from the thesis's node 6 until both nodes have a valid realisation.
    """
    count = node_stats["count"].min(FORCE)
    for k in range(min(THESIS_HISTOGRAM_NODE, int(ds["i"].max())), 0, -1):
        if int(count.sel(i=k, j=k)) > 0 and int(count.sel(i=-k, j=k)) > 0:
            return [(k, k), (-k, k)]
    return [(0, 0)]


def _fmt(value, digits: int = 3) -> str:
    if value is None:
        return "n/a"
    if isinstance(value, float):
        return f"{value:.{digits}g}" if math.isfinite(value) else "n/a"
    return str(value)


def _where(site: Mapping) -> str:
    return f"node (i, j) = ({site['node'][0]}, {site['node'][1]}), F_BH = {site['blankholder_force_N']:g} N"


#: The rare-event estimators (``uqdrape.reliability.importance_sampling``'s ``method``) in words.
RARE_METHODS = {"importance": "importance sampling at the most probable point of subset levels",
                "subset": "subset simulation in independent rounds (no most probable point carries the probability)",
                "montecarlo": "plain Monte Carlo (failure is not rare)",
                "below": "subset levels that reached no failure"}


def rare_rows(record: Mapping) -> list[tuple[str, str, str]]:
    """(quantity, value, how) of each force level of a rare-event record
    (``uqdrape.workflow.rare``), e.g. ("P(lock_margin >= 1) at 126 N", "1.02e-03",
    "CoV 0.09, 2,650 drapes, importance sampling ..., 313 standard variables"); an upper
    bound reads "< 1.6e-03", and an estimate above its target CoV says so and why."""
    units = QOI_ATTRS[record["qoi"]]["units"]
    unit = "" if units == "1" else " deg" if units == "degree" else f" {units}"
    rows = []
    for level in record["levels"]:
        below = level["method"] == "below"
        note = f": {level['note']}" if level.get("note") else ""  # a record of an older run has none
        short = f" (NOT TRUSTED: above the target {record['cov']:g}{note})" if level["cov"] > record["cov"] else ""
        rows.append((f"P({record['qoi']} >= {record['threshold']:g}{unit}) at {level['force']:g} N",
                     ("< " if below else "") + f"{level['probability']:.3g}",
                     (f"no drape reached the threshold: an upper bound, not an estimate, {level['drapes']:,} drapes"
                      if below else f"CoV {level['cov']:.2f}{short}, {level['drapes']:,} drapes") +
                     f", {RARE_METHODS[level['method']]}, {record['variables']} standard variables"))
    return rows


def _rows(numbers: Mapping, extra: Mapping, dominant: list | None) -> list[tuple[str, str, str]]:
    """(quantity, value, where/how) rows of the headline table; only what applies to the kind."""
    kind, levels = numbers["kind"], numbers["blankholder_force_levels_N"]
    count = {SENSITIVITY: "sample evaluations", SWEPT: "drapes in the sweep"}.get(kind, "realisations N")
    rows = [("study kind", kind, _KIND_TEXT[kind]), (count + (" per level" if len(levels) > 1 else ""),
                                                      str(numbers["realizations"]), ""),
            ("blank-holder force levels (N)", ", ".join(f"{f:g}" for f in levels), "")]
    model = numbers["blankholder_model"]
    rows.append(("blank-holder friction model", model,
                 "friction on the radial draw-in only (thesis Eq 5.1-5.5)" if model == "radial"
                 else "friction on the whole plan slip of the held fabric"))
    failed = {name: k for name, k in numbers["node_status"].items() if name != "ok"}
    rows.append(("valid fraction", f"{numbers['valid_fraction']:.4f}", "valid node values / all node values"
                 + ("; not placed: " + ", ".join(f"{name} {k:,}" for name, k in failed.items()) if failed else "")))
    site = numbers["max_abs_mean_shear_deg"]
    rows.append(("max |shear| (deg)" if kind == DETERMINISTIC else "max |mean shear| (deg)", _fmt(site["value"]),
                 _where(site) if site["value"] is not None else ""))
    if numbers["max_sd_deg"] is not None:
        site = numbers["max_sd_deg"]
        rows.append(("max sd of shear (deg)", _fmt(site["value"]), _where(site) if site["value"] is not None else ""))
    if kind == RANDOM:
        wr = numbers["max_wrinkle_probability"]
        if wr is None or wr["value"] is None:
            rows.append(("max wrinkle risk", "n/a", "no locking angle (a geodesic drape without a material)"
                         if wr is None else "no valid node"))
        elif wr["value"] == 0:  # no node to name: any would be arbitrary
            rows.append((f"max wrinkle risk {wr['measure']}", f"0 [0, {wr['upper']:.3f}]",
                         f"no node at risk in {numbers['realizations']} drapes; the upper limit is the "
                         f"{wr['interval']}'s for 0 of {numbers['realizations']}"))
        else:
            rows.append((f"max wrinkle risk {wr['measure']}", f"{wr['value']:.3f} [{wr['lower']:.3f}, {wr['upper']:.3f}]",
                         f"{_where(wr)}; {wr['interval']}"))
        sn = numbers["samples_needed"]
        rows.append((f"N needed for ±{sn['half_width_deg']:g}° ({sn['confidence']:.0%}) at the most variable node",
                     str(sn["value"]), f"{_where(sn)}, sd = {sn['sd_deg']:.3g}° (Student t)") if sn else
                    ("N needed for ±1° at the most variable node", "n/a", "no spread in the ensemble"))
    for d in dominant or ():
        rows.append((f"largest total-order Sobol' index ST, F_BH = {d['blankholder_force_N']:g} N", f"{d['factor']} {d['ST']:.2f} ± {d['ST_conf']:.2f}",
                     f"of {d['qoi']}, the largest over all factors and quantities of interest"))
    rows.extend((str(k), _fmt(v["value"]), v["how"]) if isinstance(v, dict) else (str(k), _fmt(v), "supplied by the caller")
                for k, v in extra.items())
    return rows


def _check_extra(summary) -> dict:
    """The caller's headline items, a (value, how) pair as {"value": value, "how": how}."""
    if summary is None:
        return {}
    if not isinstance(summary, Mapping):
        raise ValueError(f"summary must be a mapping of name -> number or string, got {type(summary).__name__}")
    scalar = (str, int, float, bool)
    out = {}
    for key, value in summary.items():
        pair = isinstance(value, tuple) and len(value) == 2 and isinstance(value[0], scalar) and isinstance(value[1], str)
        if not isinstance(key, str) or not (value is None or isinstance(value, scalar) or pair):
            raise ValueError(f"summary[{key!r}] = {value!r}: keys must be strings and values numbers, "
                             "strings, booleans, None or (value, how) pairs of one of them and a string")
        out[key] = dict(zip(("value", "how"), value)) if pair else value
    return out


#: Ensembles up to this size (bytes) are read into memory once for their report; the
#: statistics and figures otherwise compute lazily (dask), each re-reading the chunk files.
LOAD_BYTES = 2**30


def write_report(ds: xr.Dataset, out_dir, *, title: str, description: str | None = None,
                 study_text: str | None = None, histogram_nodes: Sequence[Sequence[int]] | None = None,
                 experimental_csv=None, summary: Mapping | None = None, sensitivity: xr.Dataset | None = None,
                 sensitivity_maps: xr.Dataset | None = None, wall_time_s: float | None = None,
                 replicates: int | None = None, rare: Mapping | None = None,
                 formats: Sequence[str] = ()) -> Path:
    """Write the figures of ensemble ``ds``'s report plan, ``summary.json`` and ``index.html``
    into ``out_dir``; returns the index.html path.

    ``ds``: ensemble or drape Dataset (put in the ensemble layout, ``uqdrape.schema.by_force``;
    read into memory first if it is at most ``LOAD_BYTES``);
    its kind (``uqdrape.stats.study_kind``) picks the figures (``uqdrape.report.plan``).
    ``title``: short page title; ``description``: a sentence under it. ``study_text``:
    the study TOML, shown once, verbatim. ``histogram_nodes``: [(i, j), ...] (default:
    node 6, or the largest valid k below it, of a + and a - max-shear line).
    ``experimental_csv``: measured points overlaid on the line plots (checked first).
    ``summary``: extra headline items (name -> number/string, or a (value, how) pair whose
    ``how`` fills the table's where/how column) for the table and the JSON (under
    ``extra``; a pair as {"value", "how"}). ``sensitivity`` / ``sensitivity_maps``: the QoI indices and
    node-shear index maps of a sensitivity run (``uqdrape.workflow.open_sensitivity``),
    shown first. ``wall_time_s``: the run's wall time for the provenance line. ``rare``:
    the run's rare-event record (``uqdrape.workflow.rare``), a headline row per force level
    and ``rare`` in the JSON. ``formats``: vector formats (``style.VECTOR_FORMATS``: svg, pdf)
    written beside the PNGs and linked from the captions.
    """
    if REALIZATION not in ds.dims:
        raise ValueError(f"write_report needs an ensemble Dataset with a {REALIZATION!r} dim; dims: {dict(ds.sizes)}")
    if ds.nbytes <= LOAD_BYTES:  # one read of the chunk files, not one per statistic
        ds = ds.compute()
    ds = by_force(ds)
    if not isinstance(title, str) or not title.strip():
        raise ValueError(f"title must be a non-empty string, got {title!r}")
    extra = _check_extra(summary)
    formats = check_formats(formats)
    points = read_experimental(experimental_csv) if experimental_csv is not None else None
    if sensitivity is not None and sensitivity.attrs.get("method") not in INDICES:
        raise ValueError(f"sensitivity has method={sensitivity.attrs.get('method')!r} in its attributes; "
                         f"expected one of {tuple(INDICES)}")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)

    kind = study_kind(ds)
    node_stats = node_statistics(ds, replicates=replicates)
    exceedance = wrinkle_risk(ds) if kind == RANDOM else None
    nodes = default_histogram_nodes(ds, node_stats) if histogram_nodes is None else histogram_nodes
    c = Context(ds, kind, out, node_stats, exceedance, nodes, points, sensitivity, sensitivity_maps)
    with vector_formats(formats):  # the figures, and the page linking their vector copies
        sens_items, items = render(SENSITIVITY_PLAN, c), render(PLAN, c)

        numbers = headline_numbers(ds, node_stats=node_stats, exceedance=exceedance)
        dominant = dominant_factors(sensitivity) if sensitivity is not None and "ST" in sensitivity else None
        record = {"title": title, "description": description, **numbers, "extra": extra, "provenance": provenance(wall_time_s),
                  "attrs": {k: _json_attr(v) for k, v in ds.attrs.items()},
                  "figures": [item[0].name for item in sens_items + items if not isinstance(item, str)],
                  "notes": [item for item in sens_items + items if isinstance(item, str)]}
        if rare is not None:
            record["rare"] = {k: v for k, v in rare.items() if k != "key"}
        if sensitivity is not None:
            record["sensitivity"] = {k: _json_attr(sensitivity.attrs[k])
                                     for k in ("method", "base_samples", "n_evaluations", "conf_level")}
            record["sensitivity"]["largest_ST"] = dominant
        summary_path = out / "summary.json"
        write_text_atomic(summary_path, json.dumps(record, indent=2, allow_nan=False) + "\n")
        write_statistics(ds, node_stats, exceedance, out / STATISTICS_FILE, title)

        section = "" if sensitivity is None else _sensitivity_section(sensitivity, sens_items)
        rows = _rows(numbers, extra, dominant) + (rare_rows(rare) if rare is not None else [])
        page = _page(record, ds, rows, items, study_text, summary_path.name, section)
        index = write_text_atomic(out / "index.html", page)
    return index


def write_statistics(ds: xr.Dataset, node_stats: xr.Dataset, exceedance: xr.Dataset | None, path, title: str):
    """The per-node statistics of ensemble ``ds`` as a CF netCDF file: the shear's mean, sd,
    skewness, quantiles and their confidence limits (deg), the count of valid drapes and,
    for a random sample, the wrinkle risk with its limits, on the mean node positions x,
    y, z (mm; the ``coordinates`` of every node variable), per blank-holder level."""
    stats = node_stats.assign({name: ds[name].mean(REALIZATION).assign_attrs(ds[name].attrs)
                               for name in ("x", "y", "z")})
    for name in ("mean", "sd", "mean_lower", "mean_upper", "quantile_value", "quantile_lower", "quantile_upper"):
        stats[name].attrs.setdefault("units", "degree")
    if exceedance is not None:
        risk = exceedance[["probability", "probability_lower", "probability_upper"]]
        stats = stats.assign({f"wrinkle_{k}": v.assign_attrs(units="1", long_name=f"{exceedance.attrs['risk']}"
                                                                                   f" ({k.replace('_', ' ')})")
                              for k, v in risk.data_vars.items()})
    stats = stats.compute()
    stats.attrs = {k: v for k, v in ds.attrs.items() if k not in _HIDDEN_ATTRS}
    encoded, encoding = cf_encode(stats, title=f"uqdrape per-node statistics: {title}", history="uqdrape report")
    return write_atomic(path, lambda tmp: encoded.to_netcdf(tmp, engine="netcdf4", encoding=encoding))


def _json_attr(value):
    """A Dataset attribute as a JSON value (NaN -> None, numpy scalars -> Python)."""
    if hasattr(value, "item") and getattr(value, "ndim", 1) == 0:
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, (str, int, float, bool)) or value is None:
        return value
    return str(value)


def _sensitivity_section(indices: xr.Dataset, items) -> str:
    """HTML: the sample, a table of the indices (± confidence half-width) per QoI and
    factor with one column per blank-holder level, and the sensitivity figures."""
    esc = html.escape
    method = indices.attrs["method"]
    pairs = INDICES[method]
    forces = [float(f) for f in indices[FORCE].values]
    head = "".join(f"<th>F_BH = {f:g} N</th>" for f in forces)
    body = []
    for q in indices["qoi"].values:
        for factor in indices["factor"].values:
            cells = []
            for f in forces:
                at = indices.sel({"qoi": q, "factor": factor, FORCE: f})
                cells.append(" / ".join(f"{float(at[v]):.2f} ± {float(at[c]):.2f}" for v, c, _ in pairs))
            body.append(f"<tr><th>{esc(str(q))}</th><th>{esc(str(factor))}</th>"
                        + "".join(f"<td class=\"num\">{esc(c)}</td>" for c in cells) + "</tr>")
    unit = "trajectories" if method == "morris" else "base samples"
    return f"""<h2>Sensitivity</h2>
<p>{esc(method)} sample: {indices.attrs['base_samples']} {unit}, {indices.attrs['n_evaluations']} drapes per
blank-holder level (the same rows at every level); a random field is one group of its Karhunen&ndash;Lo&egrave;ve
variables. Table: {esc(" / ".join(v for v, _, _ in pairs))} ± the half-width of the
{100 * indices.attrs['conf_level']:g} % bootstrap confidence interval.</p>
{figures_html(items)}
<table>
<tr><th>quantity</th><th>factor</th>{head}</tr>
{chr(10).join(body)}
</table>
"""


def _page(record, ds, rows, items, study_text, summary_name, sensitivity_html="") -> str:
    esc = html.escape
    table = "\n".join(
        f"<tr><th>{esc(q)}</th><td class=\"num\">{esc(v)}</td><td>{esc(w)}</td></tr>" for q, v, w in rows)
    attrs = "\n".join(f"<tr><th>{esc(str(k))}</th><td>{esc(_fmt(_json_attr(v)))}</td></tr>"
                      for k, v in ds.attrs.items() if k not in _HIDDEN_ATTRS)
    study = (f"<h2>Study file</h2>\n<pre>{esc(study_text)}</pre>" if study_text
             else "<p class=\"note\">No study file was given.</p>")
    description = f"<p>{esc(record['description'])}</p>" if record["description"] else ""
    return page(record["title"], f"""<h1>{esc(record['title'])}</h1>
{description}
<p class="note">{esc(provenance_line(record["provenance"]))}
Angles in degrees, lengths in mm, forces in N. Numbers also in <a href="{esc(summary_name)}">{esc(summary_name)}</a>.</p>
<h2>Headline numbers</h2>
<table>
<tr><th>quantity</th><th>value</th><th>where / how</th></tr>
{table}
</table>
{sensitivity_html}
<h2>Figures</h2>
{figures_html(items)}
{study}
<h2>Ensemble attributes</h2>
<table>
{attrs}
</table>""")
