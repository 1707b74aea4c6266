#!/usr/bin/python3
"""The find_exit command line on every real ORB-SLAM room file, and a contact sheet of its plots.

Reads ../shared/data/orbslam_rooms (next to the repository; --data to point elsewhere): every file
but the SOURCE.md notes goes through ``scripts/find_exit FILE --plot PNG --json`` (default method,
up axis -y), one process each, exactly as a user would run it. Exit status 2 (an error) counts as
a failure; 1 (a room but no exit) does not. The plots are tiled into one PNG (a grid of
thumbnails, titled by file) and the answers written to JSON.

Usage: bench/exit_contact_sheet.py [--data DIR] [--out PNG] [--json FILE] [--columns N]
Writes bench/results/exit_contact_sheet.png and bench/results/exit_real_files.json by default.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, ".."))
DATA = os.path.normpath(os.path.join(ROOT, "..", "shared", "data", "orbslam_rooms"))


def data_files(data):
    return sorted(os.path.join(d, f) for d, _, names in os.walk(data) for f in names
                  if not f.endswith(".md"))


def run_cli(path, png):
    """(exit status, parsed JSON or None, stderr) of the find_exit command on one file."""
    env = dict(os.environ, PYTHONPATH=os.path.join(ROOT, "src") + os.pathsep +
               os.environ.get("PYTHONPATH", ""), PATH="/usr/bin:" + os.environ.get("PATH", ""),
               MPLBACKEND="Agg")
    proc = subprocess.run(["/usr/bin/python3", os.path.join(ROOT, "scripts", "find_exit"), path,
                           "--plot", png, "--json"], capture_output=True, text=True, env=env,
                          timeout=300)
    try:
        answer = json.loads(proc.stdout) if proc.stdout.strip() else None
    except json.JSONDecodeError:
        answer = None
    return proc.returncode, answer, proc.stderr.strip()


def contact_sheet(entries, out, columns):
    """Tile the PNGs of entries [(label, png or None, caption)] into one figure."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.image import imread

    rows = (len(entries) + columns - 1) // columns
    fig = Figure(figsize=(2.2 * columns, 2.45 * rows), dpi=80)
    FigureCanvasAgg(fig)
    for k, (label, png, caption) in enumerate(entries):
        ax = fig.add_subplot(rows, columns, k + 1)
        ax.set_axis_off()
        if png and os.path.isfile(png):
            ax.imshow(imread(png))
        ax.set_title(f"{k}: {label}\n{caption}", fontsize=5)
    fig.subplots_adjust(left=0.01, right=0.99, bottom=0.01, top=0.99, wspace=0.04, hspace=0.3)
    fig.savefig(out)


def _label(path, data):
    rel = os.path.relpath(path, data)
    parts = rel.split(os.sep)
    repo = parts[0].split("__")[-1]
    return f"{repo}/{'/'.join(parts[-2:])}"[-44:]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--data", default=DATA)
    parser.add_argument("--out", default=os.path.join(HERE, "results", "exit_contact_sheet.png"))
    parser.add_argument("--json", default=os.path.join(HERE, "results", "exit_real_files.json"))
    parser.add_argument("--columns", type=int, default=10)
    args = parser.parse_args(argv)
    if not os.path.isdir(args.data):
        print(f"no real files at {args.data}", file=sys.stderr)
        return 2
    files = data_files(args.data)
    entries, report, errors = [], [], 0
    with tempfile.TemporaryDirectory(prefix="sparse_nav_exit_sheet_") as tmp:
        for k, path in enumerate(files):
            png = os.path.join(tmp, f"{k:03d}.png")
            code, answer, stderr = run_cli(path, png)
            errors += code == 2
            rel = os.path.relpath(path, args.data)
            if answer is not None and answer["exits"]:
                best = answer["exits"][0]
                caption = f"{answer['method']} score {best['score']:.2f}"
            else:
                caption = f"exit {code}: " + (answer["method"] if answer else stderr[-60:])
            entries.append((_label(path, args.data), png, caption))
            report.append({"file": rel, "exit_status": code, "answer": answer,
                           "stderr": stderr if code else ""})
            print(f"{k:3d} {code} {caption:40s} {rel}")
        os.makedirs(os.path.dirname(args.out), exist_ok=True)
        contact_sheet(entries, args.out, args.columns)
    with open(args.json, "w") as handle:
        json.dump({"files": len(files), "errors": errors, "results": report}, handle, indent=1)
    print(f"{len(files)} files, {errors} errors; {args.out}")
    return 1 if errors else 0


if __name__ == "__main__":
    sys.exit(main())
