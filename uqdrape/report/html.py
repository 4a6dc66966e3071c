"""``write_report``: every figure of an ensemble plus one self-contained HTML page.

The page (``index.html``) uses inline CSS and relative links to PNGs in the same
folder, so the folder can be copied or served as is. ``summary.json`` holds the same
headline numbers as the page's table (see ``uqdrape.report.summary``).
"""

from __future__ import annotations

import html
import json
import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import xarray as xr

from uqdrape.stats import line_statistics, node_statistics

from .ensemble_figures import (
    plot_convergence,
    plot_histograms,
    plot_line_statistics,
    plot_mean_map,
    plot_scalar_vs_factor,
    plot_sd_map,
    plot_sweep,
    plot_wrinkle_map,
    varying_factors,
)
from .experimental import read_experimental
from .figures import FORCE, REALIZATION, levels, plot_lines, plot_net
from .sensitivity_figures import INDICES, plot_sensitivity_bars, plot_sensitivity_map, plot_sensitivity_vs_force
from .summary import headline_numbers, wrinkle_risk

#: The node number along the max-shear lines the thesis shows histograms of (Fig 5.20).
THESIS_HISTOGRAM_NODE = 6
_CSS = """
body { font-family: system-ui, sans-serif; max-width: 1300px; margin: 1.5em auto; padding: 0 1em; color: #222; }
h1 { font-size: 1.6em; } h2 { font-size: 1.25em; margin-top: 1.6em; border-bottom: 1px solid #ccc; }
table { border-collapse: collapse; margin: 0.5em 0; } td, th { border: 1px solid #ccc; padding: 0.3em 0.7em; }
th { background: #f2f2f2; text-align: left; } td.num { text-align: right; font-variant-numeric: tabular-nums; }
figure { margin: 1.2em 0; } figure img { max-width: 100%; border: 1px solid #ddd; }
figcaption { font-size: 0.95em; color: #444; margin-top: 0.3em; }
pre { background: #f7f7f7; border: 1px solid #ddd; padding: 0.8em; overflow-x: auto; font-size: 0.9em; }
.note { color: #666; font-size: 0.9em; }
"""


def default_histogram_nodes(ds: xr.Dataset, node_stats: xr.Dataset) -> list[tuple[int, int]]:
    """Node k of a + and a - quadrant max-shear line, (k, k) and (-k, k), k = min(6, rings) or less.

    k steps down from the thesis's node 6 until both nodes have a valid realisation.
    """
    count = node_stats["count"]
    if FORCE in count.dims:
        count = count.min(FORCE)
    k_top = min(THESIS_HISTOGRAM_NODE, int(ds["i"].max()))
    for k in range(k_top, 0, -1):
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
    text = f"node (i, j) = ({site['node'][0]}, {site['node'][1]})"
    if site.get("blankholder_force_N") is not None:
        text += f", F_BH = {site['blankholder_force_N']:g} N"
    return text


def _rows(numbers: Mapping, extra: Mapping) -> list[tuple[str, str, str]]:
    """(quantity, value, where/how) rows of the headline table."""
    rows = [("realisations N" + (" per level" if numbers["blankholder_force_levels_N"] else ""),
             str(numbers["realizations"]), "")]
    if numbers["blankholder_force_levels_N"]:
        rows.append(("blank-holder force levels (N)",
                     ", ".join(f"{f:g}" for f in numbers["blankholder_force_levels_N"]), ""))
    model = numbers["blankholder_model"]
    rows.append(("blank-holder friction model", model,
                 "friction on the radial draw-in only (thesis Eq 5.1-5.5)" if model == "radial"
                 else "friction on the whole plan slip of the held fabric"))
    rows.append(("valid fraction", f"{numbers['valid_fraction']:.4f}", "valid node values / all node values"))
    for key, name in (("max_abs_mean_shear_deg", "max |mean shear| (deg)"), ("max_sd_deg", "max sd of shear (deg)")):
        site = numbers[key]
        rows.append((name, _fmt(site["value"]), _where(site) if site["value"] is not None else ""))
    wr = numbers["max_wrinkle_probability"]
    if wr is None or wr["value"] is None:
        rows.append(("max wrinkle-risk probability", "n/a", "no locking angle in the ensemble (geodesic drape "
                     "without a material)" if wr is None else "no valid node"))
    else:
        rows.append((f"max wrinkle risk {wr['measure']}",
                     f"{wr['value']:.3f} [{wr['lower']:.3f}, {wr['upper']:.3f}]",
                     f"{_where(wr)}; {wr['interval']}"))
    sn = numbers["samples_needed"]
    if sn is None:
        rows.append(("N needed for ±1° at the most variable node", "n/a", "no spread in the ensemble"))
    else:
        rows.append((f"N needed for ±{sn['half_width_deg']:g}° ({sn['confidence']:.0%}) at the most variable node",
                     str(sn["value"]), f"{_where(sn)}, sd = {sn['sd_deg']:.3g}° (Student t)"))
    rows.extend((str(k), _fmt(v), "supplied by the caller") for k, v in extra.items())
    return rows


def _check_extra(summary) -> dict:
    if summary is None:
        return {}
    if not isinstance(summary, Mapping):
        raise ValueError(f"summary must be a mapping of name -> number or string, got {type(summary).__name__}")
    for key, value in summary.items():
        if not isinstance(key, str) or not (value is None or isinstance(value, (str, int, float, bool))):
            raise ValueError(f"summary[{key!r}] = {value!r}: keys must be strings and values numbers, "
                             "strings, booleans or None")
    return dict(summary)


def write_report(ds: xr.Dataset, out_dir, *, title: str, study_text: str | None = None,
                 histogram_nodes: Sequence[Sequence[int]] | None = None, experimental_csv=None,
                 summary: Mapping | None = None, sensitivity: xr.Dataset | None = None,
                 sensitivity_maps: xr.Dataset | None = None) -> Path:
    """Write every figure of ensemble ``ds``, ``summary.json`` and ``index.html`` into ``out_dir``.

    ``ds``: ensemble Dataset (realization, i, j; optional leading ``blankholder_force``).
    ``study_text``: the study TOML, shown verbatim. ``histogram_nodes``: [(i, j), ...]
    (default: node 6, or the largest valid k below it, of a + and a - max-shear line).
    ``experimental_csv``: measured points overlaid on the line plots (checked first).
    ``summary``: extra headline items (name -> number/string) for the table and the
    JSON (under ``extra``). Figures that do not apply are left out (no wrinkle map
    without a locking angle, no sweep plot without a sweep, no sd map, wrinkle map, line
    statistics, histograms or convergence for one realisation per level); an ensemble
    without a sweep whose realisations vary exactly one scalar factor (e.g. ``skew``)
    gets ``vs_<factor>.png`` (energies and line means against it). ``sensitivity`` /
    ``sensitivity_maps``: the QoI indices and node-shear index maps of a sensitivity run
    (``uqdrape.workflow.open_sensitivity``), drawn as bar charts, index-vs-force lines
    and maps, and tabulated in a Sensitivity section. Returns the index.html path.
    """
    if REALIZATION not in ds.dims:
        raise ValueError(f"write_report needs an ensemble Dataset with a {REALIZATION!r} dim; dims: {dict(ds.sizes)}")
    if not isinstance(title, str) or not title.strip():
        raise ValueError(f"title must be a non-empty string, got {title!r}")
    extra = _check_extra(summary)
    points = read_experimental(experimental_csv) if experimental_csv is not None else None
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)

    node_stats = node_statistics(ds)
    # one realisation (per level) is a deterministic drape: no spread, so no spread figures
    spread = ds.sizes[REALIZATION] > 1
    exceedance = wrinkle_risk(ds) if spread else None
    nodes = default_histogram_nodes(ds, node_stats) if histogram_nodes is None else histogram_nodes
    figures: list[tuple[Path, str]] = []
    for force, level in levels(ds):
        name = "net.png" if force is None else f"net_{force:g}N.png"
        at = "" if force is None else f" at F_BH = {force:g} N"
        figures.append((plot_net(level, out / name, realization=0),
                        f"Draped net of the first realisation{at}, cells coloured by node shear (deg)."))
    figures += [
        (plot_lines(ds, out / "lines.png", realization=0, experimental=points),
         "Shear along the four max-shear lines of the first realisation (red: i·j > 0 quadrants, blue: the "
         "others)" + (", with the measured points" if points is not None else "") + "."),
        (plot_mean_map(ds, out / "mean_shear.png", node_stats=node_stats),
         "Ensemble-mean node shear on the mean node positions." if spread else "Node shear on the node positions."),
    ]
    factors = varying_factors(ds) if FORCE not in ds.dims else []
    if len(factors) == 1:
        figures.append((plot_scalar_vs_factor(ds, out / f"vs_{factors[0]}.png", factors[0]),
                        f"Blank-holder energy per quadrant and in total, and the max-shear line means, against "
                        f"the one sampled factor, {factors[0]} (thesis Fig 5.6 for the skew)."))
    if spread:
        figures.append((plot_sd_map(ds, out / "sd_shear.png", node_stats=node_stats),
                        "Standard deviation of node shear on the mean node positions."))
    if exceedance is not None:
        figures.append((plot_wrinkle_map(ds, out / "wrinkle_risk.png", exceedance=exceedance),
                        f"Wrinkle risk {exceedance.attrs['risk']} per node (a cell locks past its own "
                        "branch's locking angle), with its binomial confidence interval at the node of highest risk."))
    if spread:
        figures += [
            (plot_line_statistics(ds, out / "line_statistics.png", line_stats=line_statistics(ds),
                                  experimental=points),
             "Shear against distance from the tip along the max-shear lines: mean ± 1 sd per node and the band "
             "holding the central 95 % of realisations (thesis Figs 5.18/5.19)."),
            (plot_histograms(ds, out / "histograms.png", nodes),
             "Histograms of node shear with the fitted Normal (thesis Fig 5.20)."),
            (plot_convergence(ds, out / "convergence.png", node_stats=node_stats),
             "Convergence of the mean shear with N at the most variable node."),
        ]
    if FORCE in ds.dims:
        figures.append((plot_sweep(ds, out / "sweep.png"),
                        "Mean shear of the + and − quadrant max-shear lines and their asymmetry against "
                        "blank-holder force (mean ± 1 sd over the realisations)."))

    sens_figures = [] if sensitivity is None else _sensitivity_figures(ds, sensitivity, sensitivity_maps, out)

    numbers = headline_numbers(ds, node_stats=node_stats, exceedance=exceedance)
    record = {"title": title, **numbers, "extra": extra, "attrs": {k: _json_attr(v) for k, v in ds.attrs.items()},
              "figures": [p.name for p, _ in figures + sens_figures]}
    if sensitivity is not None:
        record["sensitivity"] = {k: _json_attr(sensitivity.attrs[k])
                                 for k in ("method", "base_samples", "n_evaluations", "conf_level")}
    summary_path = out / "summary.json"
    summary_path.write_text(json.dumps(record, indent=2, allow_nan=False) + "\n", encoding="utf-8")

    section = "" if sensitivity is None else _sensitivity_section(sensitivity, sens_figures)
    page = _page(title, ds, _rows(numbers, extra), figures, study_text, summary_path.name, section)
    index = out / "index.html"
    index.write_text(page, encoding="utf-8")
    return index


def _json_attr(value):
    """A Dataset attribute as a JSON value (NaN -> None, numpy scalars -> Python)."""
    if hasattr(value, "item") and getattr(value, "ndim", 1) == 0:
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, (str, int, float, bool)) or value is None:
        return value
    return str(value)


def _figures_html(figures) -> str:
    esc = html.escape
    return "\n".join(
        f"<figure><a href=\"{esc(p.name)}\"><img src=\"{esc(p.name)}\" alt=\"{esc(caption)}\"></a>"
        f"<figcaption>{esc(caption)}</figcaption></figure>"
        for p, caption in figures
    )


def _sensitivity_figures(ds: xr.Dataset, indices: xr.Dataset, maps: xr.Dataset | None, out: Path) -> list:
    """The sensitivity figures of a run as [(path, caption)]."""
    method = indices.attrs.get("method")
    if method not in INDICES:
        raise ValueError(f"sensitivity has method={method!r} in its attributes; expected one of {tuple(INDICES)}")
    ci = f"{100 * indices.attrs['conf_level']:g} % bootstrap confidence intervals"
    figures = [(plot_sensitivity_bars(indices, out / "sensitivity_bars.png"),
                f"Sensitivity indices of each quantity of interest (rows) per blank-holder level (columns), "
                f"with {ci} as error bars.")]
    if FORCE in indices.dims:
        figures.append((plot_sensitivity_vs_force(indices, out / "sensitivity_vs_force.png"),
                        f"Indices of each factor against blank-holder force, bands: {ci}."))
    if maps is not None:
        for var, _, name in INDICES[method]:
            figures.append((plot_sensitivity_map(ds, maps, out / f"sensitivity_map_{var}.png", index=var),
                            f"{name} of node shear per factor (rows) and blank-holder level (columns), on the "
                            "ensemble-mean net; blank where a node is invalid in some evaluation."))
    return figures


def _sensitivity_section(indices: xr.Dataset, figures) -> str:
    """HTML: the design, a table of the indices (± confidence half-width) per QoI and
    factor with one column per blank-holder level, and the sensitivity figures."""
    esc = html.escape
    method = indices.attrs["method"]
    pairs = INDICES[method]
    forces = [float(f) for f in indices[FORCE].values] if FORCE in indices.dims else [None]
    head = "".join(f"<th>{'value' if f is None else f'F_BH = {f:g} N'}</th>" for f in forces)
    body = []
    for q in indices["qoi"].values:
        for factor in indices["factor"].values:
            cells = []
            for f in forces:
                at = indices.sel(qoi=q, factor=factor, **({} if f is None else {FORCE: f}))
                cells.append(" / ".join(f"{float(at[v]):.2f} ± {float(at[c]):.2f}" for v, c, _ in pairs))
            body.append(f"<tr><th>{esc(str(q))}</th><th>{esc(str(factor))}</th>"
                        + "".join(f"<td class=\"num\">{esc(c)}</td>" for c in cells) + "</tr>")
    what = " / ".join(v for v, _, _ in pairs)
    unit = "trajectories" if method == "morris" else "base samples"
    return f"""<h2>Sensitivity</h2>
<p>{esc(method)} design: {indices.attrs['base_samples']} {unit}, {indices.attrs['n_evaluations']} drapes per
blank-holder level (the realisations of this report are the design's rows, the same at every level); a random
field is one group of its Karhunen&ndash;Lo&egrave;ve variables. Table: {esc(what)} ± the half-width of the
{100 * indices.attrs['conf_level']:g} % bootstrap confidence interval.</p>
<table>
<tr><th>quantity</th><th>factor</th>{head}</tr>
{chr(10).join(body)}
</table>
{_figures_html(figures)}
"""


def _page(title, ds, rows, figures, study_text, summary_name, sensitivity_html="") -> str:
    esc = html.escape
    table = "\n".join(
        f"<tr><th>{esc(q)}</th><td class=\"num\">{esc(v)}</td><td>{esc(w)}</td></tr>" for q, v, w in rows
    )
    attrs = "\n".join(
        f"<tr><th>{esc(str(k))}</th><td>{esc(_fmt(_json_attr(v)))}</td></tr>" for k, v in ds.attrs.items()
    )
    figs = _figures_html(figures)
    study = (f"<h2>Study file</h2>\n<pre>{esc(study_text)}</pre>" if study_text
             else "<p class=\"note\">No study file was given.</p>")
    return f"""<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>{esc(title)}</title>
<style>{_CSS}</style>
</head>
<body>
<h1>{esc(title)}</h1>
<p class="note">uqdrape {esc(str(ds.attrs.get("uqdrape_version", "")))} report.
Angles in degrees, lengths in mm, forces in N.
Numbers also in <a href="{esc(summary_name)}">{esc(summary_name)}</a>.</p>
<h2>Headline numbers</h2>
<table>
<tr><th>quantity</th><th>value</th><th>where / how</th></tr>
{table}
</table>
<h2>Figures</h2>
{figs}
{sensitivity_html}
{study}
<h2>Ensemble attributes</h2>
<table>
{attrs}
</table>
</body>
</html>
"""
