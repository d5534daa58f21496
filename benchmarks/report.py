"""Write benchmark results: JSON, a Markdown report with the targets, and matplotlib plots."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from pycinder.util.optional import require

SYSTEMS = ("pycinder", "pycinder-scene", "python-fcl", "coal", "trimesh", "warp")

TARGETS = (
    # (scene, peer, the most pycinder may take as a multiple of the peer's time, wording)
    ("stairs", "python-fcl", 3.0, "Stairs-250: at most 3x python-fcl's time"),
    ("many", "python-fcl", 1.0, "1000 small bodies: no slower than python-fcl"),
    ("deforming", "coal", 0.5, "16 deforming bunnies: at least 2x faster than coal (refit)"),
)


def _fmt(ms: float) -> str:
    return f"{ms:.1f}" if ms >= 1 else f"{ms:.2f}"


def _systems(rows: list[dict[str, Any]]) -> list[str]:
    present = {s for r in rows for s in r["median_ms"]}
    return [s for s in SYSTEMS if s in present]


def _table(rows: list[dict[str, Any]], first: str, key: Any) -> list[str]:
    systems = _systems(rows)
    peers = [s for s in systems if s != "pycinder"]
    head = [first, "bodies", "triangles"] + [f"{s} ms" for s in systems] \
        + [f"{s} / pycinder" for s in peers] + [f"recall {s}" for s in systems] + ["false pairs"]
    out = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        med, acc = r["median_ms"], r["accuracy"]
        cells = [str(key(r)), str(r["bodies"]), str(r["triangles"])]
        cells += [_fmt(med[s]) if s in med else "-" for s in systems]
        cells += [f"{r['ratio'][s]:.2f}" if s in r.get("ratio", {}) else "-" for s in peers]
        cells += [f"{acc[s]['recall']:.4f}" if s in acc else "-" for s in systems]
        cells.append(", ".join(f"{s} {acc[s]['false']}" for s in systems if s in acc))
        out.append("| " + " | ".join(cells) + " |")
    return out


def targets(results: dict[str, Any]) -> list[tuple[str, str, bool]]:
    """Each target: wording, what was measured, met."""
    out = []
    scenes = results.get("scenes", {})
    for scene, peer, factor, words in TARGETS:
        r = scenes.get(scene)
        if r is None or peer not in r["median_ms"]:
            continue
        ours, theirs = r["median_ms"]["pycinder"], r["median_ms"][peer]
        out.append((words, f"{_fmt(ours)} ms against {_fmt(theirs)} ms: "
                           f"{ours / theirs:.2f}x {peer}'s time", ours <= factor * theirs))
    rows = list(scenes.values()) + [e for s in results.get("sweeps", {}).values() for e in s]
    if rows:
        must = sum(r["accuracy"]["pycinder"]["must"] for r in rows if "pycinder" in r["accuracy"])
        found = sum(r["accuracy"]["pycinder"]["found"] for r in rows if "pycinder" in r["accuracy"])
        false = sum(r["accuracy"]["pycinder"]["false"] for r in rows if "pycinder" in r["accuracy"])
        recall = found / must if must else 1.0
        out.append(("Recall of at least 99.9% everywhere, no false pair beyond the tolerance",
                    f"{found} of {must} pairs that must be found ({recall:.4%}), {false} false",
                    recall >= 0.999 and false == 0))
    return out


def floor_table(rows: list[dict[str, Any]]) -> list[str]:
    """The cost floor (:mod:`.floor`) as Markdown lines."""
    out = ["## Cost floor", "",
           "A fresh process per backend: importing pycinder, making a Detector (device and "
           "pipelines), its first query; then the median query of a box and a 320-triangle "
           "sphere, apart and touching, default options; python-fcl on the same two pairs "
           "(building both BVHs and the first `collide`, then one `collide`).", "",
           "| backend | import ms | Detector() ms | first query ms | query ms, apart | "
           "query ms, touching | python-fcl first ms | python-fcl ms, apart | "
           "python-fcl ms, touching |", "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        if "error" in r:
            out.append(f"| {r['backend']} | not available: {r['error'].splitlines()[-1]} |"
                       + " |" * 7)
            continue
        fcl = r.get("python-fcl") or {"first_call_ms": float("nan"),
                                      "ms": {"apart": float("nan"), "touching": float("nan")}}
        imported = r.get("import_ms")
        out.append(f"| {r['adapter']} | {_fmt(imported) if imported is not None else '-'} | "
                   f"{_fmt(r['detector_ms'])} | {_fmt(r['first_call_ms'])} | "
                   f"{_fmt(r['pycinder_ms']['apart'])} | {_fmt(r['pycinder_ms']['touching'])} | "
                   f"{_fmt(fcl['first_call_ms'])} | {fcl['ms']['apart']:.4f} | "
                   f"{fcl['ms']['touching']:.4f} |")
    return out + [""]


def markdown(results: dict[str, Any]) -> str:
    m = results["machine"]
    lines = [
        f"# Benchmark results ({m['date']})", "",
        f"- adapter: {m['adapter']}",
        f"- CPU: {m['cpu']} ({m['cores']} cores), Python {m['python']}",
        "- versions: " + ", ".join(f"{k} {v}" for k, v in m["versions"].items()),
        f"- command: `{m['command'] or 'pycinder bench'}`",
        f"- peers: {', '.join(results.get('peers', []))}",
        *[f"- left out: {name} ({why})" for name, why in results.get("left_out", {}).items()],
        "",
        "Median milliseconds per frame, all pairs of the frame; the peer's time divided by "
        "pycinder's (above 1: pycinder is faster); recall over the pairs that must be found "
        "(penetrating by at least two tolerances, exact geometry) and pairs reported though at "
        "least one tolerance apart, with pycinder's default tolerance (1% of the smaller body) "
        "for every system.", "",
    ]
    if results.get("floor"):
        lines += floor_table(results["floor"])
    if results.get("hostcpu"):
        from .hostcpu import HOW, markdown_lines, validation_lines

        rows = results["hostcpu"]
        lines += ["## Host CPU per query", "", HOW, ""] + markdown_lines(rows) + [""]
        lines += validation_lines(rows) + [""]
    met = targets(results)
    if met:
        lines += ["## Targets", "", "| target | measured | met |", "|---|---|---|"]
        lines += [f"| {w} | {what} | {'yes' if ok else '**no**'} |" for w, what, ok in met]
        lines.append("")
    scenes = results.get("scenes", {})
    if scenes:
        lines += ["## Scenes", ""] + _table(list(scenes.values()), "scene", lambda r: r["scene"])
        lines.append("")
    titles = {"sweep-extent": ("Scene extent at a fixed tolerance", "extent",
                               lambda r: f"{r['params']['extent']:g}"),
              "sweep-bodies": ("Body count at about 100k triangles", "bodies",
                               lambda r: r["bodies"]),
              "sweep-triangles": ("Triangles per body, 20 bodies", "triangles/body",
                                  lambda r: r["params"]["triangles_per_body"]),
              "sweep-tolerance": ("Stairs-250 at several tolerances", "tolerance",
                                  lambda r: f"{r['params']['tolerance']:g}")}
    for name, rows in results.get("sweeps", {}).items():
        title, first, key = titles.get(name, (name, "scene", lambda r: r["scene"]))
        lines += [f"## {title}", ""] + _table(rows, first, key) + [""]
    stages = [(name, r["pycinder_stats"]) for name, r in scenes.items() if "pycinder_stats" in r]
    if stages:
        passes = sorted({k for _, st in stages for k in st["gpu_ms"]})
        lines += ["## Where pycinder's time goes", "",
                  "One extra frame per scene with GPU timestamps (wall ms per stage, GPU ms per "
                  "pass) and what the frame did. `update`: a deforming scene's fresh vertices "
                  "checked (PreparedBodies.update, before the query); `validate`: the query's "
                  "own checks.", "",
                  "| scene | " + " | ".join(("update", "validate", "broad phase", "tiles",
                                             "upload", "gpu", "decode", "total")) + " | "
                  + " | ".join(passes) + " | candidates | tiles | pixels | triangles | samples |",
                  "|" + "---|" * (14 + len(passes))]
        for name, st in stages:
            w, g = st["wall_ms"], st["gpu_ms"]
            lines.append(
                f"| {name} | " + " | ".join(_fmt(w.get(k, 0.0)) for k in
                                            ("update", "validate", "broad phase", "tiles",
                                             "upload", "gpu", "decode", "total")) + " | "
                + " | ".join(_fmt(g.get(p, 0.0)) for p in passes)
                + f" | {st['candidates']} | {st['tiles']} | {st['pixels']} | {st['triangles']} "
                  f"| {st['samples']} |")
        lines.append("")
    trips = [(name, st) for name, st in stages if "submissions" in st]
    if trips:
        lines += ["## GPU round trips and host work", "",
                  "Per frame of each scene (an unprofiled frame): submissions and buffer maps "
                  "pycinder made; host milliseconds of its own work before the frame's "
                  "submission (what the GPU waits for: `submitted_ms` less the waits for the GPU "
                  "broad phase's and the GPU planner's maps, shown apart) and per query in total "
                  "(update, validation, that work and decoding; profiled: the frame with GPU "
                  "timestamps); the same frame planned on the GPU (`planner=\"gpu\"`); and the "
                  "GPU busy fraction of the profiled frame (its passes' timestamps over its wall "
                  "time).", "",
                  "| scene | submissions / maps | host ms before submit (waits) | host ms per "
                  "query (profiled) | planner=\"gpu\": submissions / maps | host ms before "
                  "submit (waits) | host ms per query | GPU busy |",
                  "|---|---|---|---|---|---|---|---|"]
        for name, st in trips:
            busy = "-" if st["gpu_busy"] is None else f"{100 * st['gpu_busy']:.0f}%"
            g = st.get("gpu_planner")
            planned = "| - | - | -" if g is None else (
                f"| {g['submissions']} / {g['maps']} | {_fmt(g['host_ms_before_submit'])} "
                f"({_fmt(g['waited_ms'])}) | {_fmt(g['host_ms_per_query'])}")
            lines.append(f"| {name} | {st['submissions']} / {st['maps']} | "
                         f"{_fmt(st['host_ms_before_submit'])} ({_fmt(st.get('waited_ms', 0))}) "
                         f"| {_fmt(st.get('host_ms_per_query', 0))} "
                         f"({_fmt(st.get('host_ms_per_query_profiled', 0))}) {planned} | "
                         f"{busy} |")
        lines.append("")
    if results.get("modes"):
        lines += ["## The scene strategy's readback and self-interference modes", "",
                  "| scene | options | ms / frame | bytes read | pairs missed | false pairs | "
                  "possibly_lost | self-interference px |", "|---|---|---|---|---|---|---|---|"]
        for r in results["modes"]:
            opts = ", ".join(f"{k}={v}" for k, v in r["options"].items())
            lines.append(f"| {r['scene']} ({r['scene_name']}) | {opts} | {_fmt(r['median_ms'])} | "
                         f"{r['median_bytes']} | {r['missed_pairs']} / {r['must']} | "
                         f"{r['false_pairs']} | {r['possibly_lost']} | "
                         f"{r['self_interference_pixels']} |")
        lines.append("")
    if results.get("manager"):
        lines += ["## CollisionManager against trimesh's (python-fcl)", "",
                  "200 random primitives, a probe, a second manager of 50 objects, and 700 small "
                  "spheres tested against one box; median ms per call, in the same run. "
                  "Distances of overlapping objects: pycinder gives the deepest pair, trimesh "
                  "the first its traversal meets.", "",
                  "| call | pycinder ms | trimesh ms | trimesh / pycinder | answers (pycinder; "
                  "trimesh) |", "|---|---|---|---|---|"]
        for r in results["manager"]:
            med, ans = r["median_ms"], r["answers"]
            lines.append(f"| `{r['call']}` | {_fmt(med['pycinder'])} | {_fmt(med['trimesh'])} | "
                         f"{r['ratio']:.2f} | {ans['pycinder']}; {ans['trimesh']} |")
        lines.append("")
    if results.get("contacts"):
        lines += ["## Contact accuracy against analytic pairs", "",
                  "The deepest contact of each pair; normal error in degrees, depth and its error "
                  "(true depth in the first column). pycinder at tolerance 0.005.", "",
                  "| pair | true depth | pycinder contacts | pycinder normal error | pycinder depth | "
                  "python-fcl contacts | python-fcl normal error | python-fcl depth |",
                  "|---|---|---|---|---|---|---|---|"]
        for r in results["contacts"]:
            p, f = r["pycinder"], r["python-fcl"]
            lines.append(f"| {r['pair']} | {r['true_depth']:.3f} | {p['contacts']} | "
                         f"{p['normal_error_deg']:.1f} | {p['depth']:.4f} | {f['contacts']} | "
                         f"{f['normal_error_deg']:.1f} | {f['depth']:.4f} |")
        lines.append("")
    if results.get("contract"):
        from .contract import markdown as contract_markdown

        lines += contract_markdown(results["contract"])
    if results.get("batch"):
        from .batch import markdown as batch_markdown

        lines += batch_markdown(results["batch"])
    if results.get("broadphase"):
        from .broadbench import markdown as broadphase_markdown

        lines += broadphase_markdown(results["broadphase"])
    if results.get("building"):
        from .building import markdown as building_markdown

        lines += building_markdown(results["building"]) + [""]
    loops = {"soak": "three small bodies passed as fresh (vertices, faces) arrays every frame",
             "soak-deforming": "a ball whose vertices change every frame, touching a box"}
    for key, what in loops.items():
        soak = results.get(key)
        if not soak:
            continue
        if key == "soak" or "soak" not in results:
            lines += ["## Memory over a long loop", ""]
        lines += [f"{soak['frames']} frames of {what} ({soak['seconds']:.0f} s): resident memory "
                  f"{soak['rss_start_mib']:.1f} MiB after start-up, {soak['rss_end_mib']:.1f} MiB "
                  f"at the end, largest growth {soak['rss_growth_mib']:.1f} MiB; "
                  f"{soak['topology_builds']} topologies built; caches hold "
                  f"{soak['cache_bytes'] / 2**20:.2f} MiB.", ""]
    return "\n".join(lines)


def require_matplotlib() -> Any:
    """matplotlib, or an ImportError that says what to install (checked before a run starts)."""
    return require("matplotlib", "the benchmark plots", "bench")


def plots(results: dict[str, Any], out: Path) -> list[Path]:
    matplotlib = require_matplotlib()
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    paths: list[Path] = []

    def save(fig: Any, name: str) -> None:
        fig.tight_layout()
        paths.append(out / f"{name}.png")
        fig.savefig(paths[-1], dpi=120)
        plt.close(fig)

    adapter = results["machine"]["adapter"]
    scenes = results.get("scenes", {})
    if scenes:
        fig, ax = plt.subplots(figsize=(8, 4))
        names = list(scenes)
        systems = _systems(list(scenes.values()))
        width = 0.8 / len(systems)
        for i, s in enumerate(systems):
            vals = [scenes[n]["median_ms"].get(s, float("nan")) for n in names]
            ax.bar([x + i * width for x in range(len(names))], vals, width, label=s)
        ax.set_xticks([x + 0.4 - width / 2 for x in range(len(names))], names)
        ax.set_yscale("log")
        ax.set_ylabel("median ms per frame (log)")
        ax.set_title(f"All-pairs collision checks, {adapter}", fontsize=9)
        ax.legend(fontsize=8)
        save(fig, "scenes")
    xkeys = {"sweep-extent": ("extent", "scene extent (world units; tolerance fixed)"),
             "sweep-bodies": ("count", "bodies (total triangles fixed)"),
             "sweep-triangles": ("triangles_per_body", "triangles per body"),
             "sweep-tolerance": ("tolerance", "tolerance (world units)")}
    for name, entries in results.get("sweeps", {}).items():
        key, label = xkeys.get(name, ("count", name))
        xs = [e["params"][key] for e in entries]
        rows = 2 if name == "sweep-extent" else 1
        fig, axes = plt.subplots(rows, 1, figsize=(6, 3.2 * rows), squeeze=False)
        ax = axes[0, 0]
        for s in _systems(entries):
            ax.plot(xs, [e["median_ms"].get(s, float("nan")) for e in entries], "o-", label=s)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_ylabel("median ms per frame")
        ax.set_xlabel(label)
        ax.set_title(f"{name}, {adapter}", fontsize=9)
        ax.legend(fontsize=8)
        if rows == 2:
            ax = axes[1, 0]
            for s in _systems(entries):
                ax.plot(xs, [e["accuracy"][s]["recall"] for e in entries], "o-", label=s)
            ax.set_xscale("log")
            ax.set_ylim(0, 1.05)
            ax.set_ylabel("recall")
            ax.set_xlabel(label)
        save(fig, name)
    soaks = {"soak": "fresh (vertices, faces) arrays every frame",
             "soak-deforming": "a body deforming every frame"}
    if any(results.get(k) for k in soaks):
        fig, ax = plt.subplots(figsize=(6, 3))
        for key, label in soaks.items():
            soak = results.get(key)
            if soak:
                ax.plot([k for k, _ in soak["samples"]],
                        [r / 2**20 for _, r in soak["samples"]], label=label)
        ax.set_xlabel("frame")
        ax.set_ylabel("resident memory (MiB)")
        ax.set_ylim(0, None)
        ax.legend(fontsize=8)
        save(fig, "soak")
    return paths


def write(results: dict[str, Any], out_dir: str | Path, stem: str = "results") -> list[Path]:
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = [out / f"{stem}.json", out / f"{stem}.md"]
    paths[0].write_text(json.dumps(results, indent=1, default=float))
    paths[1].write_text(markdown(results))
    return paths + plots(results, out)
