"""The study's results as an error-versus-time plot per scene (matplotlib PNG), bench/study/README.md
(per scene: every setting's time, peak memory, coefficients and error) and the main README's preset
table (between the markers `<!-- study:presets begin -->` and `<!-- study:presets end -->`)."""
from __future__ import annotations

import pathlib
import re

# The plots' time axis: CPU time summed over threads, steadier than wall time on a shared machine
# (on 2 idle cores the wall time is about half of it for both the solver and Cycles).
T = "cpu_seconds"
BEGIN, END = "<!-- study:presets begin -->", "<!-- study:presets end -->"


def _f(value, digits=1, percent=False):
    if value in ("", None) or float(value) != float(value):  # blank or NaN
        return "–"
    return f"{100 * float(value):.{digits}f}%" if percent else f"{float(value):.{digits}f}"


def plot(path, scene, rows):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker

    fig, ax = plt.subplots(figsize=(7, 5))
    solves = [r for r in rows if r["method"] == "bsgi"]
    # The knobs are swept around the preview preset (around draft in a smoke run).
    preview = next((r for r in solves if r["setting"] == "preview"), None) or \
        next((r for r in solves if r["setting"] == "draft"), None)
    knobs = dict.fromkeys(r["knob"] for r in solves if r["knob"] != "preset")
    for knob in knobs:
        pts = [r for r in solves if r["knob"] == knob] + ([preview] if preview else [])
        pts.sort(key=lambda r: float(r[T]))
        ax.plot([float(r[T]) for r in pts], [100 * float(r["rel_rmse"]) for r in pts], "o-", alpha=0.55,
                ms=4, label=f"bsgi, {preview['setting'] if preview else 'preset'} with {knob}")
        for r in pts:
            if r is not preview:
                ax.annotate(str(r["value"]), (float(r[T]), 100 * float(r["rel_rmse"])), fontsize=7,
                            xytext=(3, 3), textcoords="offset points")
    presets = [r for r in solves if r["knob"] == "preset"]
    ax.plot([float(r[T]) for r in presets], [100 * float(r["rel_rmse"]) for r in presets], "k*", ms=12,
            label="bsgi presets")
    for r in presets:
        ax.annotate(r["value"], (float(r[T]), 100 * float(r["rel_rmse"])), fontsize=9, weight="bold",
                    xytext=(5, -10), textcoords="offset points")
    cycles = sorted((r for r in rows if r["method"] != "bsgi"), key=lambda r: float(r[T]))
    if cycles:
        ax.plot([float(r[T]) for r in cycles], [100 * float(r["rel_rmse"]) for r in cycles], "s--",
                color="tab:red", label="Cycles bake (samples)")
        for r in cycles:
            ax.annotate(str(r["value"]), (float(r[T]), 100 * float(r["rel_rmse"])), fontsize=8,
                        color="tab:red", xytext=(4, 4), textcoords="offset points")
    noise = rows[0]["reference_noise"]
    ax.set_xscale("log")
    ax.set_yscale("log")
    plain = matplotlib.ticker.FuncFormatter(lambda v, _: f"{v:g}")
    ax.xaxis.set_major_formatter(plain)
    ax.yaxis.set_major_formatter(plain)
    ax.yaxis.set_minor_formatter(plain)  # errors often span less than a decade
    ax.set_xlabel("CPU time (s, summed over threads)")
    ax.set_ylabel("relative RMSE against Mitsuba 3 (%)")
    ax.set_title(f"{scene}: error versus time (reference noise {100 * float(noise):.1f}%)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def scene_table(rows) -> str:
    lines = ["| setting | wall time (s) | CPU time (s) | peak memory (MB) | coefficients / texels | error | "
             "diffuse surfaces | glossy surfaces |", "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['setting']} | {_f(r['seconds'], 2)} | {_f(r['cpu_seconds'], 2)} | {_f(r['peak_mb'])} | "
                     f"{r['coefficients']} | "
                     f"{_f(r['rel_rmse'], 1, True)} | {_f(r['rel_rmse_diffuse'], 1, True)} | "
                     f"{_f(r['rel_rmse_glossy'], 1, True)} |")
    return "\n".join(lines)


def presets_table(by_scene) -> str:
    """Per scene: the three presets and the Cycles bakes, time and error."""
    lines = ["| scene | setting | wall time | CPU time | error (all / glossy pairs) |", "|---|---|---|---|---|"]
    for scene, rows in by_scene.items():
        for r in rows:
            if r["knob"] in ("preset", "samples"):
                glossy = _f(r["rel_rmse_glossy"], 1, True)
                lines.append(f"| {scene} | {r['setting']} | {_f(r['seconds'], 1)} s | {_f(r[T], 1)} s | "
                             f"{_f(r['rel_rmse'], 1, True)}"
                             f"{' / ' + glossy if glossy != '–' else ''} |")
    return "\n".join(lines)


def write(out, rows, readme=None):
    out = pathlib.Path(out)
    (out / "plots").mkdir(parents=True, exist_ok=True)
    by_scene = {}
    for r in rows:
        by_scene.setdefault(r["scene"], []).append(r)
    parts = ["# The speed–accuracy study (`make study`)", "",
             "Generated by `bench/study/run_study.py` (do not edit): per scene, the solver's presets, one knob at a "
             "time around the preview preset (where the preview took over a minute of CPU, without spatial 32, "
             "hemisphere nodes 16x32 and, after a minute of wall time, the final preset), and Cycles baking at "
             "several sample counts. The final preset refines the surfaces its error estimate puts over 1% and "
             "solves again, within five times its first solve's rays. Anisotropic metals are rendered by Mitsuba "
             "along Blender's default tangent. "
             "Error: relative RMSE "
             "against Mitsuba 3 at the same random visible (point, direction) pairs; *glossy surfaces* are the "
             "pairs on glossy or transmitting surfaces, where a Cycles bake (view-independent: baked as seen along "
             "the normal) cannot follow the view. Times on a 2-core machine shared with other jobs: the wall "
             "time is what was seen, the CPU time (summed over threads, the plots' axis) is steadier; raw figures "
             "in `results.csv`.", ""]
    for scene, srows in by_scene.items():
        plot(out / "plots" / f"{scene}.png", scene, srows)
        pairs = srows[0]["pairs"]
        parts += [f"## {scene}", "", f"{pairs} pairs; reference noise {_f(srows[0]['reference_noise'], 1, True)}.", "",
                  f"![{scene}: error versus time](plots/{scene}.png)", "", scene_table(srows), ""]
    (out / "README.md").write_text("\n".join(parts))
    if readme is not None:
        text = pathlib.Path(readme).read_text()
        if BEGIN in text and END in text:
            table = presets_table(by_scene)
            text = re.sub(re.escape(BEGIN) + ".*?" + re.escape(END), lambda m: f"{BEGIN}\n{table}\n{END}", text,
                          flags=re.S)
            pathlib.Path(readme).write_text(text)
