"""Write benchmark results: JSON, a Markdown table, and matplotlib plots."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

SYSTEMS = ("pycinder", "python-fcl", "coal", "trimesh")


def _fmt(ms: float) -> str:
    return f"{ms:.1f}" if ms >= 1 else f"{ms:.2f}"


def markdown(results: dict[str, Any]) -> str:
    m = results["machine"]
    lines = [
        f"# Benchmark results ({m['date']})", "",
        f"- adapter: {m['adapter']}",
        f"- CPU: {m['cpu']} ({m['cores']} cores), Python {m['python']}",
        "- versions: " + ", ".join(f"{k} {v}" for k, v in m["versions"].items()),
        f"- pycinder: resolution {results['resolution']}, options {results['pycinder_options']}",
        f"- command: `{m['command'] or 'pycinder bench'}`", "",
        "Median milliseconds per frame (all pairs checked), the peer's time divided by pycinder's "
        "(above 1: pycinder is faster), and accuracy against exact geometry (manifold3d, 5% "
        "band): recall on clear overlaps and clearly separate pairs reported.", "",
    ]
    rows = list(results.get("scenes", {}).values())
    for sweep in results.get("sweeps", {}).values():
        rows += sweep
    if rows:
        lines += ["| scene | bodies | triangles | res | " + " | ".join(
            f"{s} ms" for s in SYSTEMS) + " | fcl / pyc | coal / pyc | trimesh / pyc | "
            "recall (pyc, fcl, coal) | false (pyc, fcl, coal) |",
            "|" + "---|" * (4 + len(SYSTEMS) + 5)]
        for r in rows:
            med, acc, sp = r["median_ms"], r["accuracy"], r["speedup_vs"]
            cells = [_fmt(med[s]) if s in med else "-" for s in SYSTEMS]
            ratios = [f"{sp[s]:.2f}" if s in sp else "-" for s in SYSTEMS[1:]]
            rec = ", ".join(f"{acc[s]['recall']:.3f}" if s in acc else "-" for s in SYSTEMS[:3])
            fal = ", ".join(str(acc[s]["false"]) if s in acc else "-" for s in SYSTEMS[:3])
            lines.append(f"| {r['scene']} | {r['bodies']} | {r['triangles']} | "
                         f"{r.get('resolution', '')} | " + " | ".join(cells) + " | "
                         + " | ".join(ratios) + f" | {rec} | {fal} |")
        lines.append("")
    if results.get("modes"):
        lines += ["## Readback and self-interference modes", "",
                  "| scene | options | ms / frame | bytes read | pairs missed | false pairs | "
                  "possibly_lost | self-interference px |", "|---|---|---|---|---|---|---|---|"]
        for r in results["modes"]:
            opts = ", ".join(f"{k}={v}" for k, v in r["options"].items())
            lines.append(f"| {r['scene']} ({r['scene_name']}) | {opts} | {_fmt(r['median_ms'])} | "
                         f"{r['median_bytes']} | {r['missed_pairs']} / {r['overlaps']} | "
                         f"{r['false_pairs']} | {r['possibly_lost']} | "
                         f"{r['self_interference_pixels']} |")
        lines.append("")
    stages = [(r["scene"], r["pycinder_stats"]) for r in rows if "pycinder_stats" in r]
    if stages:
        lines += ["## Where pycinder's time goes (wall ms of the last frame)", "",
                  "| scene | " + " | ".join(("prepare", "gpu", "readback", "decode", "total"))
                  + " | bytes read |", "|---|---|---|---|---|---|---|"]
        for name, st in stages:
            w = st["wall_ms"]
            lines.append(f"| {name} | " + " | ".join(_fmt(w.get(k, 0.0)) for k in
                                                      ("prepare", "gpu", "readback", "decode",
                                                       "total")) + f" | {st['bytes_read']} |")
        lines.append("")
    return "\n".join(lines)


def plots(results: dict[str, Any], out: Path) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    paths = []
    scenes = results.get("scenes", {})
    if scenes:
        fig, ax = plt.subplots(figsize=(8, 4))
        names = list(scenes)
        width = 0.2
        for i, s in enumerate(SYSTEMS):
            vals = [scenes[n]["median_ms"].get(s, float("nan")) for n in names]
            ax.bar([x + i * width for x in range(len(names))], vals, width, label=s)
        ax.set_xticks([x + 1.5 * width for x in range(len(names))], names)
        ax.set_yscale("log")
        ax.set_ylabel("median ms per frame (log)")
        ax.set_title(f"All-pairs collision checks — {results['machine']['adapter']}", fontsize=9)
        ax.legend()
        fig.tight_layout()
        paths.append(out / "scenes.png")
        fig.savefig(paths[-1], dpi=120)
        plt.close(fig)
    for name, entries in results.get("sweeps", {}).items():
        fig, ax = plt.subplots(figsize=(6, 4))
        if name == "sweep-resolution":
            xs = [e["resolution"] for e in entries]
            ax.plot(xs, [e["median_ms"]["pycinder"] for e in entries], "o-", label="pycinder")
            for s in SYSTEMS[1:]:
                if s in entries[0]["median_ms"]:
                    ax.axhline(entries[0]["median_ms"][s], ls="--", label=s, color=f"C{SYSTEMS.index(s)}")
            ax.set_xlabel("resolution (pixels per side)")
        else:
            key = "triangles_per_body" if name == "sweep-triangles" else "count"
            xs = [e["params"][key] for e in entries]
            for s in SYSTEMS:
                ys = [e["median_ms"].get(s, float("nan")) for e in entries]
                ax.plot(xs, ys, "o-", label=s)
            ax.set_xscale("log")
            ax.set_xlabel("triangles per body" if key == "triangles_per_body"
                          else "bodies (total triangles fixed)")
        ax.set_yscale("log")
        ax.set_ylabel("median ms per frame")
        ax.set_title(name)
        ax.legend()
        fig.tight_layout()
        paths.append(out / f"{name}.png")
        fig.savefig(paths[-1], dpi=120)
        plt.close(fig)
    return paths


def write(results: dict[str, Any], out_dir: str | Path, stem: str = "results") -> list[Path]:
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = [out / f"{stem}.json", out / f"{stem}.md"]
    paths[0].write_text(json.dumps(results, indent=1, default=float))
    paths[1].write_text(markdown(results))
    try:
        paths += plots(results, out)
    except ImportError:
        pass
    return paths
