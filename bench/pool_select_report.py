#!/usr/bin/env python3
"""The tables of bench/pool_select.sh: OUT/results.md from the runs' metrics.json,
summary.json and pool_chosen.json. Every number comes from a file a run wrote; a missing run
is "-". The criteria (bench/results/README.md, "the exposure protocol"), fixed before the
runs:

  * primary metric: PSNR after a per-image affine colour fit to the truth (psnr_affine);
    secondary: raw PSNR, foreground PSNR, SSIM;
  * first, per budget and split, the positive control minus random (paired by seed, 95 %
    interval): where it does not exclude 0 the instrument cannot judge a selection there,
    and the report says so instead of ranking;
  * FillGS minus each of the six other strategies, paired by seed, every interval printed
    (none chosen as "the best"), on the primary metric, then on raw PSNR;
  * per judged camera, every row's primary metric; per seed, the window (dense minus
    control); per run, how often its chosen photographs were drawn.

    python3 bench/pool_select_report.py OUT --title "Panoptic basketball" --seeds 1,2,3 --budgets 10,30,90 --splits near,far
"""
import argparse
import functools
import json
import math
import os
import shutil
import statistics
import subprocess
import sys

STRATEGIES = ["fillgs", "random", "negative", "interpolation", "fisherrf", "coverage3d", "coverage4d", "positive"]
# FillGS's comparators, fixed before the runs: every other strategy but the positive control.
COMPARATORS = ["negative", "random", "interpolation", "fisherrf", "coverage3d", "coverage4d"]
PRIMARY, TARGET = "psnr_affine", 0.25  # the primary metric, and the half-width the seeds aim at (dB)


class ReportError(Exception):
    """Bad input to the report: one line naming the file and what is wrong."""


@functools.lru_cache(maxsize=None)
def load(path):
    """A run's JSON file (read once; callers only read it), or None where the run has not written it."""
    try:
        with open(path) as f:
            return checked_record(path, json.load(f))
    except FileNotFoundError:
        return None
    except (ValueError, UnicodeDecodeError) as e:
        raise ReportError(f"{path}: not a JSON file ({e})") from None
    except IsADirectoryError:
        raise ReportError(f"{path}: a folder, not a JSON file") from None


def number(value, path, where):
    """A finite number from a kept record; one line naming the file and the key otherwise."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ReportError(f"{path}: {where} is {json.dumps(value)[:40]}, not a finite number")
    return float(value)


def checked_record(path, value):
    """A summary.json or pool_chosen.json as the pool script's runs write them, checked once
    where it is read: every field the report uses has its type, or one line names the file."""
    if value is None:
        return None
    def need(ok, what):
        if not ok:
            raise ReportError(f"{path}: {what}")
    need(isinstance(value, dict), "expected a JSON object")
    name = os.path.basename(path)
    if name == "pool_chosen.json":
        need(isinstance(value.get("chosen"), list), "'chosen' is not a list")
        for i, c in enumerate(value["chosen"]):
            need(isinstance(c, dict) and all(k in c for k in ("camera", "frame", "score")), f"chosen[{i}] lacks camera, frame or score")
            need(isinstance(c["camera"], (str, int)) and isinstance(c["frame"], int) and not isinstance(c["frame"], bool),
                 f"chosen[{i}] has a camera or frame of the wrong type")
            number(c["score"], path, f"chosen[{i}].score")
    elif name == "summary.json":
        if "virtual_views" in value:
            number(value["virtual_views"], path, "virtual_views")
        if "rounds" in value:
            need(isinstance(value["rounds"], list), "'rounds' is not a list")
            for i, r in enumerate(value["rounds"]):
                need(isinstance(r, dict) and isinstance(r.get("seconds"), dict), f"rounds[{i}] has no seconds")
                for key, v in (("views_added", r.get("views_added")), ("mean_weight", r.get("mean_weight")), ("seconds.select", r["seconds"].get("select"))):
                    need(v is not None, f"rounds[{i}] lacks {key}")
                    number(v, path, f"rounds[{i}].{key}")
    return value


def gnuplot_text(text):
    """`text` inside a gnuplot single-quoted string: '' for a quote, and no line break or
    backquote, which would end the command or run a shell (a title is the user's text)."""
    return "".join(" " if c in "\r\n`" or ord(c) < 32 else c for c in text).replace("'", "''")


def fmt(values, digits=2):
    values = [v for v in values if v is not None and not (isinstance(v, float) and math.isnan(v))]
    if not values:
        return "–"
    m = statistics.mean(values)
    if len(values) == 1:
        return f"{m:.{digits}f}"
    return f"{m:.{digits}f} ± {statistics.stdev(values):.{digits}f}"


def t975(df):
    """The 0.975 quantile of Student's t with df >= 1 degrees of freedom: its distribution
    function's closed form for integer df (Abramowitz and Stegun 26.7.3-4) inverted by bisection."""
    def central(t):  # P(|T| <= t)
        theta = math.atan(t / math.sqrt(df))
        c2 = math.cos(theta) ** 2
        term = total = 1.0
        if df % 2 == 0:
            for k in range(2, df - 1, 2):
                term *= c2 * (k - 1) / k
                total += term
            return math.sin(theta) * total
        if df == 1:
            return 2 * theta / math.pi
        for k in range(3, df - 1, 2):
            term *= c2 * (k - 1) / k
            total += term
        return 2 / math.pi * (theta + math.sin(theta) * math.cos(theta) * total)
    lo, hi = 0.0, 1000.0
    for _ in range(200):
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if central(mid) < 0.95 else (lo, mid)
    return (lo + hi) / 2


def interval(diffs):
    """Paired differences -> (mean, SD, 95 % half-width, seeds the SD needs for +-TARGET dB), the
    half-width t(0.975, n - 1) SD / sqrt(n); None where fewer than 2 seeds."""
    n = len(diffs)
    if n < 2:
        return None
    sd = statistics.stdev(diffs)
    need = next((m for m in range(2, 1000) if t975(m - 1) * sd / math.sqrt(m) <= TARGET), None)
    return statistics.mean(diffs), sd, t975(n - 1) * sd / math.sqrt(n), need


def write_atomic(path, text):
    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        f.write(text)
    os.replace(tmp, path)


def write_chart(out, chart, budgets, title):
    """OUT/gain.csv and gain.gp, and gain.png where gnuplot is installed: each strategy's gain
    over the control, one bar per budget."""
    ks = [k for k in budgets if any(c[1] == k for c in chart)]
    names = [st for st in STRATEGIES if any(c[0] == st for c in chart)]
    table = {(c[0], c[1]): c for c in chart}
    rows = ["strategy," + ",".join(f"K{k},K{k}_sd" for k in ks)]
    for st in names:
        cells = []
        for k in ks:
            c = table.get((st, k))
            cells += [f"{c[2]:.4f}", f"{c[3]:.4f}"] if c else ["NaN", "NaN"]
        rows.append(st + "," + ",".join(cells))
    colours = ["#3c78b4", "#e0872c", "#4aa04a", "#b44a4a"]
    width = 0.8 / len(ks)
    plots = []
    for i, k in enumerate(ks):
        x = f"($0 - 0.4 + {width / 2 + i * width:.4f})"
        plots.append(f"'gain.csv' skip 1 using {x}:{2 + 2 * i}:({width * 0.9:.4f}) with boxes lc rgb '{colours[i % len(colours)]}' title 'K = {k}'")
        plots.append(f"'' skip 1 using {x}:{2 + 2 * i}:{3 + 2 * i} with yerrorbars lc rgb '#404040' pt 7 ps 0 notitle")
    gp = [f"# gain.png from gain.csv (written by bench/pool_select_report.py); re-plot with: gnuplot gain.gp",
          "set terminal pngcairo size 720,480 noenhanced font 'DejaVu Sans,10'",
          "set datafile separator ','", "set datafile missing 'NaN'", "set border 3 lc rgb '#404040'", "set tics nomirror",
          "set grid ytics lc rgb '#dddddd' lt 1", "set style fill solid 0.85 noborder", "set output 'gain.png'",
          f"set title '{gnuplot_text(title)}: gain over the control per strategy and budget'", "set ylabel 'PSNR gain over the control (dB)'",
          "set key top right", "set xzeroaxis lt 1 lc rgb '#404040'",
          "set xtics scale 0 (" + ", ".join(f"'{st}' {i}" for i, st in enumerate(names)) + ")",
          f"set xrange [-0.6:{len(names) - 0.4}]", "set yrange [*<0:0<*]", "set offsets 0, 0, graph 0.08, graph 0.05",
          "plot " + ", \\\n     ".join(plots)]
    write_atomic(os.path.join(out, "gain.csv"), "\n".join(rows) + "\n")
    write_atomic(os.path.join(out, "gain.gp"), "\n".join(gp) + "\n")
    if not shutil.which("gnuplot"):
        return False
    r = subprocess.run(["gnuplot", "gain.gp"], cwd=out, capture_output=True, text=True)
    if r.returncode != 0:
        sys.stderr.write(f"pool_select_report: gnuplot gain.gp failed: {r.stderr.strip()}\n")
        return False
    return True


def write_interval_chart(out, name, rows, series, title):
    """OUT/NAME.csv and NAME.gp, and NAME.png where gnuplot is installed: a forest plot, one row
    per label (top to bottom), each series' 95 % interval as a bar with its mean as a point,
    filled where the interval excludes 0 (the layout of fillgs's own interval charts,
    src/io/chart.cpp). rows: [(label, {series: (mean, low, high)})]."""
    colours = ["#3c78b4", "#e0872c", "#4aa04a", "#b44a4a"]
    lines, extent = ["series,y,estimate,low,high,separated,row_name,series_name"], 0.5
    for k, sname in enumerate(series):
        offset = 0.0 if len(series) == 1 else 0.5 * (k / (len(series) - 1) - 0.5)
        for r, (label, cells) in enumerate(rows):
            if sname not in cells:
                continue
            m, lo, hi = cells[sname]
            extent = max(extent, abs(lo), abs(hi))
            lines.append(f"{k},{r + offset:.4f},{m:.6f},{lo:.6f},{hi:.6f},{1 if lo > 0 or hi < 0 else 0},\"{label}\",{sname}")
    plots = []
    for k, sname in enumerate(series):
        for sep in (True, False):
            plots.append(f"'{name}.csv' skip 1 using ($1 == {k} && $6 {'>' if sep else '<'} 0.5 ? $3 : NaN):2:4:5 with xerrorbars "
                         f"pt {7 if sep else 6} ps 1.3 lw 2 lc rgb '{colours[k % 4]}' " + (f"title '{sname}'" if sep else "notitle"))
    gp = [f"# {name}.png from {name}.csv (written by bench/pool_select_report.py); re-plot with: gnuplot {name}.gp",
          f"set terminal pngcairo size 900,{min(1200, max(300, 140 + 34 * len(rows)))} noenhanced font 'DejaVu Sans,10'",
          "set datafile separator ','", "set border 3 lc rgb '#404040'", "set tics nomirror", f"set output '{name}.png'",
          f"set title '{gnuplot_text(title)}'", "set xlabel 'PSNR difference (dB)'", "set key outside right top vertical",
          "set grid xtics lc rgb '#dddddd' lt 1", f"set yrange [{len(rows) - 0.5}:-0.5]", "set ytics scale 0",
          "set ytics (" + ", ".join("'" + gnuplot_text(label) + f"' {r}" for r, (label, _) in enumerate(rows)) + ")",
          f"set xrange [{-1.1 * extent:.4f}:{1.1 * extent:.4f}]", "set arrow from 0, graph 0 to 0, graph 1 nohead dt 2 lc rgb '#404040'",
          "plot " + ", \\\n     ".join(plots)]
    write_atomic(os.path.join(out, f"{name}.csv"), "\n".join(lines) + "\n")
    write_atomic(os.path.join(out, f"{name}.gp"), "\n".join(gp) + "\n")
    if not shutil.which("gnuplot"):
        return False
    r = subprocess.run(["gnuplot", f"{name}.gp"], cwd=out, capture_output=True, text=True)
    if r.returncode != 0:
        sys.stderr.write(f"pool_select_report: gnuplot {name}.gp failed: {r.stderr.strip()}\n")
        return False
    return True


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("out")
    ap.add_argument("--title", default="Panoptic basketball")
    ap.add_argument("--seeds", default="1,2,3")
    ap.add_argument("--budgets", default="10,30,90")
    ap.add_argument("--splits", default="near,far")
    ap.add_argument("--strategies", default=",".join(STRATEGIES), help="the strategies the script ran (their rows, in this order)")
    a = ap.parse_args()
    seeds = [x.strip() for x in a.seeds.split(",")]
    budgets = [x.strip() for x in a.budgets.split(",")]
    splits = [x.strip() for x in a.splits.split(",")]
    strategies = [x.strip() for x in a.strategies.split(",")]
    for flag, given in (("--seeds", seeds), ("--budgets", budgets), ("--splits", splits), ("--strategies", strategies)):
        twice = sorted({x for x in given if given.count(x) > 1})
        if twice or "" in given:
            # A seed counted twice would pair a run with itself: a zero-width "separated" interval.
            ap.error(f"{flag} {','.join(given)}: " + (f"{twice[0]} is given twice" if twice else "an empty item"))
    out = a.out

    def run_dir(seed, run_id):
        return os.path.join(out, f"s{seed}", run_id)

    def metrics(seed, run_id, split):
        """The split's metrics object of a run, or None where the run has not written it."""
        path = os.path.join(run_dir(seed, run_id), f"eval_{split}", "metrics.json")
        m = load(path)
        if m is None:
            return None, path
        if not isinstance(m, dict) or (split in m and not isinstance(m[split], dict)):
            raise ReportError(f"{path}: expected an object with a '{split}' object of metrics")
        return m.get(split), path

    def metric(seed, run_id, split, key):
        m, path = metrics(seed, run_id, split)
        return None if m is None else number(m.get(key), path, f"{split}.{key}")

    def per_camera(seed, run_id, split, key):
        """{camera: the mean of `key` over its views} from the run's per-view rows."""
        m, path = metrics(seed, run_id, split)
        if m is None or "per_view" not in m:
            return {}
        cols = m.get("per_view_columns")
        if not isinstance(cols, list) or "camera" not in cols or key not in cols or not isinstance(m["per_view"], list):
            raise ReportError(f"{path}: {split}.per_view has no '{key}' column")
        ci, ki = cols.index("camera"), cols.index(key)
        by = {}
        for r, row in enumerate(m["per_view"]):
            if not isinstance(row, list) or len(row) != len(cols):
                raise ReportError(f"{path}: {split}.per_view[{r}] is not a row of {len(cols)} values")
            v = number(row[ki], path, f"{split}.per_view[{r}].{key}")
            if v is not None:
                by.setdefault(str(row[ci]), []).append(v)
        return {c: statistics.mean(v) for c, v in by.items()}

    def summary(seed, run_id):
        return load(os.path.join(run_dir(seed, run_id), "summary.json"))

    def seconds(seed, run_id):
        s = summary(seed, run_id)
        if not s:
            return None
        path = os.path.join(run_dir(seed, run_id), "summary.json")
        try:
            if "rounds" not in s:  # a training run
                return {"select": None, "train": number(s.get("seconds"), path, "seconds"), "total": number(s.get("seconds"), path, "seconds")}
            return {"select": sum(number(r["seconds"]["select"], path, "rounds[].seconds.select") for r in s["rounds"]),
                    "train": number(s["seconds"]["train"], path, "seconds.train"), "total": number(s["seconds"]["total"], path, "seconds.total")}
        except (KeyError, TypeError) as e:
            raise ReportError(f"{path}: not a run summary (no {e})") from None

    def chosen(seed, st, K):
        return load(os.path.join(out, f"s{seed}", f"choose.{st}.K{K}", "pool_chosen.json"))

    def draws_of_chosen(seed, st, K):
        """The mean number of draws of the photographs a strategy chose, in the model trained on
        them (its summary.json's per-view draws), or None where either record is missing."""
        s, p = summary(seed, f"scratch.{st}.K{K}"), chosen(seed, st, K)
        if not s or not p or "draws" not in s:
            return None
        path = os.path.join(run_dir(seed, f"scratch.{st}.K{K}"), "summary.json")
        d = s["draws"]
        if not isinstance(d, dict) or not isinstance(d.get("per_view"), list):
            raise ReportError(f"{path}: draws.per_view is not a list")
        table = {}
        for r, row in enumerate(d["per_view"]):
            if not isinstance(row, list) or len(row) != 3:
                raise ReportError(f"{path}: draws.per_view[{r}] is not [camera, frame, draws]")
            table[(str(row[0]), row[1])] = number(row[2], path, f"draws.per_view[{r}]")
        got = [table.get((str(c["camera"]), c["frame"])) for c in p["chosen"]]
        if None in got:
            raise ReportError(f"{path}: a chosen photograph is not among the views it trained on")
        return statistics.mean(got) if got else None

    def values(run_id, key, split, seed_list):
        return [metric(s, run_id, split, key) for s in seed_list]

    def seeds_with(run_id, seed_list):
        return [s for s in seed_list if all(metric(s, run_id, sp, PRIMARY) is not None for sp in splits)]

    def paired(x, y, sp, key=PRIMARY):
        return [metric(s, x, sp, key) - metric(s, y, sp, key) for s in seeds
                if metric(s, x, sp, key) is not None and metric(s, y, sp, key) is not None]

    lines = [f"# Which camera-times help most: {a.title}, real pool photographs (the exposure protocol)", ""]
    lines.append(f"Seeds {a.seeds}. Primary metric: PSNR after a per-image affine colour fit to the truth (\"affine\"); secondary: raw PSNR, "
                 "foreground PSNR (inside the dataset's foreground masks; – without masks) and SSIM; each on the judged cameras "
                 f"({', '.join(splits)}), mean ± standard deviation over the seeds a row's numbers come from (its last column). "
                 "Every model trained with every photograph equally likely at every stage and a fixed number of draws per photograph "
                 "(draws: the mean over its chosen photographs of how often the model trained on each). Seconds: the training.")

    # The references: the window per seed, and what the time curriculum does on the training cameras.
    ref_seeds = [s for s in seeds if summary(s, "dense") or summary(s, "scratch.control")]
    if ref_seeds:
        lines += ["", "## The window: dense reference minus the training cameras alone, per seed (affine PSNR, dB)", "",
                  "| seed | " + " | ".join(f"{sp}: dense | control | window" for sp in splits) + " |", "|---|" + "---|---|---|" * len(splits)]
        for s in ref_seeds:
            cells = []
            for sp in splits:
                d, c = metric(s, "dense", sp, PRIMARY), metric(s, "scratch.control", sp, PRIMARY)
                cells += ["–" if d is None else f"{d:.2f}", "–" if c is None else f"{c:.2f}", "–" if d is None or c is None else f"{d - c:+.2f}"]
            lines.append(f"| {s} | " + " | ".join(cells) + " |")
    cur, ctl = summary("1", "backbone.curriculum"), summary("1", "scratch.control")
    if cur and ctl:
        lines += ["", "## What the time curriculum does (seed 1, the same draws per photograph)", "",
                  "The training cameras alone, trained with every photograph equally likely (the rule) and with the time curriculum "
                  "(`--time-ramp 0.7`, fillgs train's default), judged on the training cameras themselves and on the judged cameras:", "",
                  "| training | " + " | ".join(f"{sp}: affine | PSNR | foreground" for sp in ["train"] + splits) + " | Gaussians (moving) |",
                  "|---|" + "---|---|---|" * (len(splits) + 1) + "---|"]
        for rid, label in (("scratch.control", "every photograph equally likely"), ("backbone.curriculum", "time curriculum")):
            cells = []
            for sp in ["train"] + splits:
                for key in (PRIMARY, "psnr", "psnr_moving"):
                    v = metric("1", rid, sp, key)
                    cells.append("–" if v is None else f"{v:.2f}")
            sm = summary("1", rid)
            lines.append(f"| {label} | " + " | ".join(cells) + f" | {sm.get('gaussians', '–')} ({sm.get('moving_gaussians', '–')}) |")

    header = "| run |" + "".join(f" {sp} affine | PSNR | foreground | SSIM |" for sp in splits) + " photographs | draws | seconds | seeds |"
    rule = "|---|" + "---|---|---|---|" * len(splits) + "---|---|---|---|"

    def row(run_id, label, K=None, st=None):
        cells = f"| {label} |"
        for sp in splits:
            for key, d in ((PRIMARY, 2), ("psnr", 2), ("psnr_moving", 2), ("ssim", 3)):
                cells += f" {fmt(values(run_id, key, sp, seeds), d)} |"
        photos = [float(len(chosen(s, st, K)["chosen"])) for s in seeds if st and summary(s, run_id) and chosen(s, st, K)]
        draws = [draws_of_chosen(s, st, K) for s in seeds] if st else []
        secs = [x for x in (seconds(s, run_id) for s in seeds) if x]
        cells += f" {fmt(photos, 0)} | {fmt([d for d in draws if d is not None], 1)} | {fmt([x['train'] for x in secs], 0)} |"
        return cells + f" {','.join(seeds_with(run_id, seeds)) or '–'} |"

    def tied(st, K):
        """A strategy whose every pick scored 0 (on a static scene no Gaussian moves, so FillGS's and
        negative's scores are all 0) was chosen by the pool's order, not by its score."""
        if st in ("random", "positive"):
            return False
        scores = set()
        for s in seeds:
            p = chosen(s, st, K)
            if p:
                scores |= {c["score"] for c in p["chosen"]}
        return scores == {0.0}

    def interval_rows(pairs, key, collect=None):
        """Rows of 'x minus y' differences per split: mean ± SD, 95 % interval (bold where it excludes 0)."""
        rows = ["| difference | " + " | ".join(f"{sp}: mean ± SD | 95 % interval" for sp in splits) + f" | seeds | seeds for ±{TARGET} dB |",
                "|---|" + "---|---|" * len(splits) + "---|---|"]
        bounds = {}  # (label, split) -> the 95 % interval's (low, high)
        for x, y, label in pairs:
            cells, n, need = [], 0, []
            for sp in splits:
                d = paired(f"scratch.{x}", f"scratch.{y}", sp, key)
                iv = interval(d)
                n = max(n, len(d))
                if iv is None:
                    cells += [fmt(d), "–"]
                    continue
                m, sd, h, nd = iv
                bounds[(label, sp)] = (m - h, m + h)
                if collect is not None:
                    if not collect or collect[-1][0] != label:
                        collect.append((label, {}))
                    collect[-1][1][sp] = (m, m - h, m + h)
                text = f"[{m - h:.2f}, {m + h:.2f}]"
                cells += [f"{m:.2f} ± {sd:.2f}", f"**{text}**" if abs(m) > h else text]
                need.append(nd if h > TARGET else n)
            rows.append(f"| {label} | " + " | ".join(cells) + f" | {n} | {max(need) if need and None not in need else '–'} |")
        return rows, bounds

    chart = []  # (strategy, K, mean gain over the control, its seed spread)
    for K in budgets:
        ran = [st for st in strategies if any(summary(s, f"scratch.{st}.K{K}") for s in seeds)]
        if not ran:
            continue
        lines += ["", f"## K = {K} camera-times"]
        ties = {st for st in ran if tied(st, K)}
        intervals = []
        # 1. Can the instrument separate a better selection at this budget?
        if "positive" in ran and "random" in ran:
            rows, interval_of = interval_rows([(f"positive.K{K}", f"random.K{K}", "positive control minus random")], PRIMARY, intervals)
            lines += ["", "### The positive control", "", "The positive control (the pool photographs nearest the judged cameras, spread over "
                      "the clip) minus random, paired by seed (affine PSNR, dB):", ""] + rows
            # Separated means ahead of random: a positive control whose interval lies below 0
            # does worse than random, which shows no better selection being told apart.
            bounds = {sp: interval_of.get(("positive control minus random", sp)) for sp in splits}
            blind = [sp for sp in splits if not (bounds[sp] and bounds[sp][0] > 0)]
            behind = [sp for sp in blind if bounds[sp] and bounds[sp][1] < 0]
            lines += [""]
            if len(paired(f"scratch.positive.K{K}", f"scratch.random.K{K}", splits[0])) < 2:
                lines.append(f"At K = {K} fewer than two seeds have both runs: no interval yet, so nothing here is ranked.")
            elif blind:
                lines.append(f"**At K = {K} the positive control does not separate from random on the {', '.join(blind)} split"
                             f"{'s' if len(blind) > 1 else ''}: there the instrument cannot judge a selection at this budget, and FillGS's "
                             "differences below are printed, not ranked.**")
                if behind:
                    lines.append(f"On the {', '.join(behind)} split{'s' if len(behind) > 1 else ''} the positive control is behind random (its "
                                 "interval below 0): the photographs nearest the judged cameras score worse there than a random choice, "
                                 "so that split cannot tell a better selection either.")
            else:
                lines.append(f"At K = {K} the positive control separates from random on every split: the instrument can tell a better selection here.")
        else:
            lines += ["", f"No positive control at K = {K}: nothing shows the instrument can separate a better selection here; the "
                      "differences below are printed, not ranked."]
        # 2. The table.
        lines += ["", "### Every run", "", header, rule,
                  row("dense", "dense reference (training + every pool photograph)"),
                  row("backbone", "backbone (the model every strategy chooses on)"),
                  row("scratch.control", "training cameras alone (control)")]
        for st in ran:
            lines.append(row(f"scratch.{st}.K{K}", f"{st}.K{K}" + (" (every score 0, pool order)" if st in ties else ""), K, st))
        # 3. FillGS against each other strategy, fixed in advance.
        if "fillgs" in ran and "fillgs" in ties:
            lines += ["", "FillGS's picks all scored 0 (no Gaussian moves): its selection is the pool's order, so its differences are not applicable."]
        elif "fillgs" in ran:
            pairs = [(f"fillgs.K{K}", f"{o}.K{K}", f"FillGS minus {o}") for o in COMPARATORS if o in ran and o not in ties]
            rows, _ = interval_rows(pairs, PRIMARY, intervals)
            raw, _ = interval_rows(pairs, "psnr")
            lines += ["", "### FillGS minus each other strategy", "",
                      "Paired by seed, mean ± SD over the seeds and the 95 % interval (t with n − 1 degrees of freedom), **bold** where it "
                      f"excludes 0; seeds for ±{TARGET} dB: how many seeds the measured SD needs for that half-width. Primary metric (affine PSNR, dB):",
                      ""] + rows + ["", "Raw PSNR (secondary, dB):", ""] + raw
            for o in COMPARATORS:
                if o in ties:
                    lines.append(f"FillGS minus {o}: not applicable ({o}'s picks all scored 0).")
        if intervals and write_interval_chart(out, f"intervals_K{K}", intervals, splits,
                                              f"{a.title}, K = {K}: 95 % intervals, affine PSNR (filled: excludes 0)"):
            lines += ["", f"![FillGS minus each and the positive control minus random, K = {K}, 95 % intervals](intervals_K{K}.png)"]
        # 4. Per judged camera.
        cams = {}
        for sp in splits:
            for rid in ["scratch.control"] + [f"scratch.{st}.K{K}" for st in ran]:
                for s in seeds:
                    for c in per_camera(s, rid, sp, PRIMARY):
                        cams.setdefault(sp, [])
                        if c not in cams[sp]:
                            cams[sp].append(c)
        if cams:
            cols = [(sp, c) for sp in splits for c in sorted(cams.get(sp, []), key=lambda x: (len(x), x))]
            lines += ["", f"### Per judged camera (affine PSNR over the camera's frames, mean over the seeds, dB)", "",
                      "| run | " + " | ".join(f"{sp} {c}" for sp, c in cols) + " |", "|---|" + "---|" * len(cols)]
            for rid, label in [("dense", "dense reference"), ("scratch.control", "control")] + [(f"scratch.{st}.K{K}", st) for st in ran]:
                cells = []
                for sp, c in cols:
                    v = [per_camera(s, rid, sp, PRIMARY).get(c) for s in seeds]
                    v = [x for x in v if x is not None]
                    cells.append(f"{statistics.mean(v):.2f}" if v else "–")
                lines.append(f"| {label} | " + " | ".join(cells) + " |")
        # 5. Each strategy's gain over the control, for the chart.
        for st in ran:
            gains = []
            for s in seeds:
                v = [metric(s, f"scratch.{st}.K{K}", sp, PRIMARY) for sp in splits]
                c = [metric(s, "scratch.control", sp, PRIMARY) for sp in splits]
                if all(x is not None for x in v + c):
                    gains.append(statistics.mean(v) - statistics.mean(c))
            if gains:
                chart.append((st, K, statistics.mean(gains), statistics.stdev(gains) if len(gains) > 1 else 0.0))
        # 6. What each chose.
        picks = {}
        for st in ran:
            for s in seeds:
                p = chosen(s, st, K)
                if p:
                    picks.setdefault(st, {})[s] = {(str(c["camera"]), c["frame"]) for c in p["chosen"]}
        if picks:
            def distinct(st, part):
                return statistics.mean(len({pair[part] for pair in v}) for v in picks[st].values())
            lines += ["", f"Distinct pool cameras / frames among the {K} camera-times chosen (mean over the seeds): " +
                      "; ".join(f"{st} {distinct(st, 0):.1f} / {distinct(st, 1):.1f}" for st in ran if st in picks) + "."]
        if len(picks) > 1:
            names = [st for st in ran if st in picks]
            lines += ["", f"Share of camera-times two strategies both chose at K = {K} (|A ∩ B| / K, mean over the seeds):", "",
                      "| | " + " | ".join(names) + " |", "|---|" + "---|" * len(names)]
            for x in names:
                cells = []
                for y in names:
                    share = [len(picks[x][s] & picks[y][s]) / max(1, len(picks[x][s])) for s in seeds if s in picks[x] and s in picks[y]]
                    cells.append(f"{statistics.mean(share):.2f}" if share else "–")
                lines.append(f"| {x} | " + " | ".join(cells) + " |")
            lines += ["", f"What each strategy chose (camera × frame, seed {seeds[0]}; each run's own picture and list are "
                          f"s{seeds[0]}/choose.<strategy>.K{K}/pool_chosen.png and .json): ![chosen](chosen_K{K}_s{seeds[0]}.png)"]
    if chart and write_chart(out, chart, budgets, a.title):
        lines += ["", "Gain over the control (affine PSNR, mean over the splits, paired within each seed; bars: mean, "
                      "whiskers: ± standard deviation over the seeds):", "", "![gain over the control](gain.png)"]
    lines += ["", "![ground truth | control | positive control | random | FillGS, the first seed](compare.png)", ""]
    write_atomic(os.path.join(out, "results.md"), "\n".join(lines))
    sys.stdout.write("\n".join(lines))
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except ReportError as e:
        sys.stderr.write(f"pool_select_report: {e}\n")
        sys.exit(1)
