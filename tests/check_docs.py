#!/usr/bin/env python3
"""Checks the project's documents (run by CTest).

  check_docs.py REPO                       the documents: headline figures equal the files
                                           they cite, links resolve, nothing reads as a diary
  check_docs.py REPO --walkthrough FILLGS  runs README's "Use it on your own 4D model" block
                                           on a small synthetic scene with that fillgs binary

Exit status 0 when everything holds; otherwise one line per problem and status 1.
"""
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile

DOCS = ["README.md", "data/README.md", "src/README.md", "bench/README.md", "bench/results/README.md", "tests/README.md"]
README_MAX_LINES = 300

# Words of a lab notebook, machine paths and references no reader can follow.
FORBIDDEN = [
    (r"\bthis commit\b", "'this commit'"),
    (r"\bsessions?\b", "'session'"),
    (r"\bissue\s*#?\d+", "an issue number"),
    (r"\bthe issue'?s?\b", "'the issue'"),
    (r"/work/|/root/|/home/|/tmp/fillgs", "a machine path"),
    (r"\b(METHOD|DESIGN|FORMATS|STYLE)\.md\b", "a document that is not in the repository"),
    (r"\bslow hour\b|\bearlier trainer\b|\btoday'?s?\b", "a dated remark"),
]


def problems_in_docs(repo):
    out = []
    for doc in DOCS:
        path = os.path.join(repo, doc)
        if not os.path.exists(path):
            out.append(f"{doc}: missing")
            continue
        text = open(path, encoding="utf-8").read()
        in_code = False
        for n, line in enumerate(text.splitlines(), 1):
            if line.startswith("```"):
                in_code = not in_code
            for pattern, what in FORBIDDEN:
                if re.search(pattern, line, re.IGNORECASE):
                    out.append(f"{doc}:{n}: {what}: {line.strip()[:120]}")
            if in_code:
                continue
            for target in re.findall(r"\]\(([^)\s]+)\)", line):
                if re.match(r"[a-z]+:", target) or target.startswith("#"):
                    continue
                file = os.path.normpath(os.path.join(os.path.dirname(path), target.split("#")[0]))
                if not os.path.exists(file):
                    out.append(f"{doc}:{n}: link to {target}, which does not exist")
    lines = open(os.path.join(repo, "README.md"), encoding="utf-8").read().count("\n")
    if lines > README_MAX_LINES:
        out.append(f"README.md: {lines} lines, more than {README_MAX_LINES}")
    return out + problems_in_headline(repo)


def cells(row):
    """The cells of a Markdown table row; '\\|' inside a cell stays a '|'."""
    parts = re.split(r"(?<!\\)\|", row.strip().strip("|"))
    return [p.strip().replace("\\|", "|") for p in parts]


def numbers(text):
    return re.findall(r"(?<![\d.])\d[\d,]*(?:\.\d+)?(?![\d.])", text)


def problems_in_headline(repo):
    """Every number of a headline row's figure appears on a line of the cited file that holds
    one of the row's keys (the backquoted texts of its source cell)."""
    out = []
    text = open(os.path.join(repo, "README.md"), encoding="utf-8").read()
    m = re.search(r"^## Headline results\n(.*?)(?=^## )", text, re.MULTILINE | re.DOTALL)
    if not m:
        return ["README.md: no '## Headline results' section"]
    rows = [l for l in m.group(1).splitlines() if l.startswith("|")][2:]
    if not rows or len(rows) > 12:
        out.append(f"README.md: the headline table has {len(rows)} rows (1 to 12)")
    for row in rows:
        c = cells(row)
        if len(c) != 3:
            out.append(f"README.md: headline row without 3 cells: {row[:80]}")
            continue
        what, figure, source = c
        links = re.findall(r"\]\(([^)#\s]+)", source)
        keys = re.findall(r"`([^`]+)`", source)
        if len(links) != 1 or not keys:
            out.append(f"README.md: headline row '{what[:50]}' must cite one file and at least one row key")
            continue
        path = os.path.join(repo, links[0])
        if not os.path.exists(path):
            out.append(f"README.md: headline row '{what[:50]}' cites {links[0]}, which does not exist")
            continue
        lines = [l for l in open(path, encoding="utf-8").read().splitlines() if any(k in l for k in keys)]
        if not lines:
            out.append(f"README.md: headline row '{what[:50]}': no line of {links[0]} holds {keys}")
            continue
        for num in numbers(figure):
            if not any(re.search(r"(?<![\d.])" + re.escape(num) + r"(?![\d])", l) for l in lines):
                out.append(f"README.md: headline row '{what[:50]}': {num} is not on the line of {links[0]} holding {keys}")
    return out


def walkthrough(repo, fillgs):
    text = open(os.path.join(repo, "README.md"), encoding="utf-8").read()
    m = re.search(r"^## Use it on your own 4D model\n.*?```sh\n(.*?)```", text, re.MULTILINE | re.DOTALL)
    if not m:
        return ["README.md: no sh block under '## Use it on your own 4D model'"]
    block = m.group(1)
    work = tempfile.mkdtemp(prefix="fillgs_walkthrough_")
    try:
        scene = os.path.join(work, "scene")
        subprocess.run([fillgs, "synth", "--out", scene, "--frames", "3", "--width", "32", "--height", "24", "--spacing", "0.1",
                        "--quiet"], check=True, stdout=subprocess.DEVNULL)
        # "Your" capture: two training cameras of the synthetic rig, judged on the others.
        cams = json.load(open(os.path.join(scene, "transforms_train.json")))
        cams["frames"] = [f for f in cams["frames"] if "/cam04/" in f["file_path"] or "/cam06/" in f["file_path"]]
        json.dump(cams, open(os.path.join(work, "cameras.json"), "w"))
        # Run from a folder that is not the checkout: the refiner's path is the checkout's own.
        env = dict(os.environ, FILLGS_SRC=repo, MODEL=os.path.join(scene, "scene.ply"), CAMERAS=os.path.join(work, "cameras.json"),
                   IMAGES=scene, HELDOUT=os.path.join(scene, "transforms_interpolation.json"), F="3",
                   PATH=os.path.dirname(os.path.abspath(fillgs)) + os.pathsep + os.environ.get("PATH", ""))
        r = subprocess.run(["bash", "-euo", "pipefail", "-c", block], cwd=work, env=env,
                           capture_output=True, text=True)
        if r.returncode != 0:
            return [f"README.md walkthrough failed (status {r.returncode}): {(r.stderr.strip().splitlines() or [''])[-1]}"]
        expected = ["work/observe/count_static.npy", "work/observe/deficiency_dynamic.npy", "work/explore/exploration.vdb", "work/select/trajectories.json",
                    "work/finetune/model.ply", "work/finetune/summary.json", "work/eval/metrics.json"]
        missing = [e for e in expected if not os.path.exists(os.path.join(work, e))]
        if missing:
            return [f"README.md walkthrough: {', '.join(missing)} not written"]
        metrics = json.load(open(os.path.join(work, "work/eval/metrics.json")))
        if "heldout" not in metrics:
            return ["README.md walkthrough: metrics.json has no 'heldout' split"]
        summary = json.load(open(os.path.join(work, "work/finetune/summary.json")))
        if summary.get("refiner") != "external" or not summary.get("virtual_views"):
            return ["README.md walkthrough: finetune refined no virtual views with the external refiner"]
        print(f"walkthrough: every step ran; held-out PSNR {metrics['heldout']['psnr']:.2f} dB, "
              f"{summary['virtual_views']} refined views")
        return []
    finally:
        shutil.rmtree(work, ignore_errors=True)


def main():
    if len(sys.argv) < 2:
        print(__doc__)
        return 2
    repo = os.path.abspath(sys.argv[1])
    if len(sys.argv) >= 4 and sys.argv[2] == "--walkthrough":
        found = walkthrough(repo, os.path.abspath(sys.argv[3]))
    else:
        found = problems_in_docs(repo)
    for p in found:
        print(p)
    if not found:
        print("documents: every check holds")
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())
