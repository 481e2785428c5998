"""wrt's speed against its peers in one table, from one ``wrt bench`` run, beside the targets.

The rows (docs/performance.md has the targets' reasons and the measured history):

=====================================================  ==========================  ==========
row                                                    ratio                       target
=====================================================  ==========================  ==========
closest hit, coherent / incoherent rays, 1 thread      wrt / Embree, rays per s    0.6 / 0.5
any hit, coherent / incoherent rays, 1 thread          wrt / Embree, rays per s    0.6
closest hit, coherent / incoherent rays, 1 thread      wrt / ``wp.Mesh``            1.5
BVH build of the throughput mesh, CPU                  ``wp.Mesh`` s / wrt s       1.0
whole process: PLY, build, 1024^2 primary rays, EXR    Mitsuba 3 s / wrt s         1.0
path tracing, Cornell box XML, 256 spp, independent    MC efficiency wrt / Mitsuba 1.0
=====================================================  ==========================  ==========

Throughput rows come from ``wrt_benchmarks.throughput``, build times from its ``build_scaling`` (the
size of the throughput mesh where it was measured, else the largest), the whole processes from
``harness.wholeprocess``. Ratios above 1 mean wrt is ahead. A row whose
inputs were not measured (no Embree, no Mitsuba, throughput skipped) reads "-".
"""

from __future__ import annotations

from wrt.tables import text_table

TARGETS = {
    "closest coherent vs Embree": 0.6,
    "closest incoherent vs Embree": 0.5,
    "any coherent vs Embree": 0.6,
    "any incoherent vs Embree": 0.6,
    "closest coherent vs wp.Mesh": 1.5,
    "closest incoherent vs wp.Mesh": 1.5,
    "BVH build vs wp.Mesh": 1.0,
    "whole process, mesh, vs Mitsuba": 1.0,
    "path tracing efficiency vs Mitsuba": 1.0,
}


def _rate(throughput: dict | None, ray_set: str, query: str, engine: str) -> float | None:
    try:
        return throughput["throughput"][ray_set][query][engine]["per_thread"]["mrays_per_s"]
    except (KeyError, TypeError):
        return None


def rows(throughput: dict | None, builds: list[dict] | None, mesh: dict | None, path: dict | None) -> list[dict]:
    """One dict per row: ``row``, ``wrt`` and ``peer`` (values with ``unit``), ``ratio``,
    ``target`` and ``met`` (None where not measured)."""
    out = []

    def add(row: str, wrt_value, peer_value, unit: str, ratio, note: str = "") -> None:
        target = TARGETS[row]
        out.append(
            {
                "row": row,
                "wrt": wrt_value,
                "peer": peer_value,
                "unit": unit,
                "ratio": ratio,
                "target": target,
                "met": None if ratio is None else ratio >= target,
                "note": note,
            }
        )

    for query in ("closest", "any"):
        for ray_set in ("coherent", "incoherent"):
            ours, theirs = _rate(throughput, ray_set, query, "wrt"), _rate(throughput, ray_set, query, "Embree")
            add(
                f"{query} {ray_set} vs Embree",
                ours,
                theirs,
                "Mrays/s, 1 thread",
                None if None in (ours, theirs) else ours / theirs,
            )
    for ray_set in ("coherent", "incoherent"):
        ours, theirs = _rate(throughput, ray_set, "closest", "wrt"), _rate(throughput, ray_set, "closest", "wp.Mesh")
        add(
            f"closest {ray_set} vs wp.Mesh",
            ours,
            theirs,
            "Mrays/s, 1 thread",
            None if None in (ours, theirs) else ours / theirs,
        )
    same = [b for b in builds or [] if throughput and b["triangles"] == throughput["mesh"]["triangles"]]
    if same or builds:
        b = (same or builds)[-1]
        note = f"{b['triangles']:,} triangles, fastest of the build-time runs; wrt on all cores, wp.Mesh on 1"
        add("BVH build vs wp.Mesh", b["wrt_s"], b["wp_mesh_s"], "s", b["wp_mesh_s"] / b["wrt_s"], note)
    else:
        add("BVH build vs wp.Mesh", None, None, "s", None)
    if mesh and "Mitsuba" in mesh:
        add(
            "whole process, mesh, vs Mitsuba",
            mesh["wrt"]["median_s"],
            mesh["Mitsuba"]["median_s"],
            "s",
            mesh["ratio"],
            f"{mesh['triangles']:,} triangles, Mitsuba {mesh['mitsuba_variant']}",
        )
    else:
        add("whole process, mesh, vs Mitsuba", mesh["wrt"]["median_s"] if mesh else None, None, "s", None)
    if path and "Mitsuba" in path:
        note = (
            f"{path['spp']} spp; MSE wrt {path['wrt']['mse']:.3g}, Mitsuba {path['Mitsuba']['mse']:.3g}; wall "
            f"{path['wrt']['median_s']:.2f} s / {path['Mitsuba']['median_s']:.2f} s"
        )
        add(
            "path tracing efficiency vs Mitsuba",
            path["wrt"]["efficiency"],
            path["Mitsuba"]["efficiency"],
            "1/(MSE s)",
            path["wrt"]["efficiency_ratio"],
            note,
        )
    else:
        add("path tracing efficiency vs Mitsuba", path["wrt"]["efficiency"] if path else None, None, "1/(MSE s)", None)
    return out


def format_rows(table: list[dict], path: dict | None = None) -> str:
    """The table as text, then the other samplers of the path-tracing comparison."""

    def num(x) -> str:
        return "-" if x is None else f"{x:.4g}"

    lines = [["row", "wrt", "peer", "unit", "ratio", "target", "met", "note"]]
    for r in table:
        met = "-" if r["met"] is None else ("yes" if r["met"] else "NO")
        lines.append(
            [r["row"], num(r["wrt"]), num(r["peer"]), r["unit"], num(r["ratio"]), f">= {r['target']}", met, r["note"]]
        )
    text = text_table(lines).split("\n")
    if path:
        for name, entry in path.items():
            if isinstance(entry, dict) and name.startswith("wrt ") and "efficiency_ratio" in entry:
                text.append(
                    f"path tracing, {name}: wall {entry['median_s']:.2f} s, MSE {entry['mse']:.3g}, efficiency "
                    f"x{entry['efficiency_ratio']:.2f} Mitsuba's"
                )
    return "\n".join(text)
