"""``meshopt filters [NAME] [--json] [--all]``: list or describe pipeline filters."""

from __future__ import annotations

from .. import strict_json
import sys

from ..errors import FilterError

HELP = "list or describe the filters usable in pipelines (ours; --all adds pymeshlab's)"


def add_args(parser) -> None:
    parser.add_argument("name", nargs="?", metavar="NAME",
                        help="a filter name or MeshLab label to describe")
    parser.add_argument("--json", action="store_true",
                        help="JSON output (name, label, description, parameters)")
    parser.add_argument("--all", action="store_true",
                        help="also list the MeshLab filters routed to pymeshlab")


def _meshlab_spec(name: str) -> dict:
    from ..pipeline import meshlab
    from ..pipeline.runner import MESHLAB_KINDS

    reverse = {v: k for k, v in meshlab.keys_table().items()}
    return {
        "name": name,
        "label": None,
        "description": f"MeshLab filter {reverse.get(name, name)!r}, run by pymeshlab",
        "origin": "pymeshlab",
        "kinds": list(MESHLAB_KINDS),
        "unsafe": name in meshlab.UNSAFE_FILTERS,
        "parameters": [dict(p) for p in meshlab.parameter_list(name)],
    }


def _describe(spec: dict) -> str:
    lines = [spec["name"] + (f"  [{spec['label']}]" if spec.get("label") else ""),
             f"  {spec['description']}", f"  origin: {spec['origin']}"]
    if spec.get("kinds"):
        lines.append(f"  meshes: {', '.join(spec['kinds'])}")
    if spec.get("aliases"):
        lines.append(f"  also: {', '.join(spec['aliases'])} (former names, still accepted)")
    if spec.get("unsafe"):
        lines.append("  refused: aborts the process without a GPU/display")
    if not spec["parameters"]:
        lines.append("  no parameters")
    for p in spec["parameters"]:
        rng = ""
        if p.get("min") is not None or p.get("max") is not None:
            rng = f" in [{p.get('min', '')}, {p.get('max', '')}]"
        choices = f" one of {p['choices']}" if p.get("choices") else ""
        former = [k for k, v in spec.get("former_parameters", {}).items() if v == p["name"]]
        also = f" (also: {', '.join(former)})" if former else ""
        lines.append(f"  {p['name']} : {p['type']} = {p['default']!r}{rng}{choices}{also}")
        if p.get("help"):
            lines.append(f"      {p['help']}")
    return "\n".join(lines)


def run(args) -> int:
    from ..pipeline import registry

    if args.name:
        cls = registry.find(args.name)
        if cls is not None:
            spec = cls.spec()
        else:
            from ..pipeline import meshlab

            ml = meshlab.resolve(args.name)
            if ml is None:
                ours = registry.names()
                from ..expressions import quoted
                from ..pipeline.params import did_you_mean

                hint = did_you_mean(args.name, ours) or meshlab.suggestions(args.name)
                raise FilterError(f"unknown filter {quoted(args.name)}{hint}")
            spec = _meshlab_spec(ml)
        print(strict_json.dumps(spec, indent=2) if args.json else _describe(spec))
        return 0
    specs = [cls.spec() for cls in registry]
    if args.all:
        from ..pipeline import meshlab

        specs += [_meshlab_spec(n) for n in meshlab.filter_names()]
    if args.json:
        strict_json.dump(specs, sys.stdout, indent=2)
        sys.stdout.write("\n")
        return 0
    width = max(len(s["name"]) for s in specs)
    for s in specs:
        origin = "" if s["origin"] in ("builtin", "pymeshlab") else f" ({s['origin']})"
        if s.get("unsafe"):
            origin += " (refused: aborts without a GPU)"
        print(f"{s['name']:<{width}}  {s['description']}{origin}")
    return 0
