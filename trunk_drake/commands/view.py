"""`trunk-drake view [--dofs sagittal|spine3d|rhythm] [--out FILE] [--serve]`: the model at rest in 3-D."""

from __future__ import annotations


def add_command(sub) -> None:
    p = sub.add_parser("view", help="the model at rest as a 3-D web page (or a live Meshcat with --serve)",
                       description="Write MyoTorso's bones, the 210 muscle paths (coloured by group) and the seat "
                                   "as a standalone HTML page that opens offline; with --serve, run a live Meshcat "
                                   "with a slider per coordinate instead.")
    p.add_argument("--dofs", choices=["sagittal", "spine3d", "rhythm"], default="sagittal",
                   help="model configuration (rhythm: the default passenger's one lumbar coordinate)")
    p.add_argument("--out", dest="page", default="model.html",  # a file, not an output folder
                   help="HTML file to write (default model.html)")
    p.add_argument("--serve", action="store_true", help="live Meshcat (prints its address; Ctrl-C stops)")
    p.add_argument("--port", type=int, default=None, help="port of the live Meshcat (default: the first free from 7000)")
    p.set_defaults(func=run)


def run(args) -> int:
    from trunk_drake.model.trunk_model import load_model
    from trunk_drake.visual import serve, view_html

    model = load_model(args.dofs)
    if args.serve:
        serve(model, port=args.port)
        return 0
    print(f"wrote {view_html(args.page, model)} (opens offline in any browser)")
    return 0
