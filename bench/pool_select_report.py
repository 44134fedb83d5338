#!/usr/bin/env python3
"""The tables of bench/pool_select.sh: OUT/results.md from the runs' metrics.json and
summary.json, a table per budget (mean +- standard deviation over the seeds), the share of
camera-times each pair of strategies chose alike, and the spread between the strategies
against the seeds' spread. Every number comes from a file a run wrote; a missing run is "-".

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

STRATEGIES = ["fillgs", "random", "negative", "interpolation", "fisherrf", "coverage3d", "coverage4d"]


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
    """Paired differences -> (mean, SD, 95 % half-width, seeds the SD needs for +-0.5 dB), the
    half-width t(0.975, n - 1) SD / sqrt(n); None where fewer than 2 seeds."""
    n = len(diffs)
    if n < 2:
        return None
    sd = statistics.stdev(diffs)
    need = next((m for m in range(2, 1000) if t975(m - 1) * sd / math.sqrt(m) <= 0.5), None)
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
    a = ap.parse_args()
    seeds = [x.strip() for x in a.seeds.split(",")]
    budgets = [x.strip() for x in a.budgets.split(",")]
    splits = [x.strip() for x in a.splits.split(",")]
    for flag, given in (("--seeds", seeds), ("--budgets", budgets), ("--splits", splits)):
        twice = sorted({x for x in given if given.count(x) > 1})
        if twice or "" in given:
            # A seed counted twice would pair a run with itself: a zero-width "separated" interval.
            ap.error(f"{flag} {','.join(given)}: " + (f"{twice[0]} is given twice" if twice else "an empty item"))
    out = a.out

    def run_dir(seed, run_id):
        return os.path.join(out, "dense") if run_id == "dense" else os.path.join(out, f"s{seed}", run_id)

    def metric(seed, run_id, split, key):
        path = os.path.join(run_dir(seed, run_id), f"eval_{split}", "metrics.json")
        m = load(path)
        if m is None:
            return None
        if not isinstance(m, dict) or (split in m and not isinstance(m[split], dict)):
            raise ReportError(f"{path}: expected an object with a '{split}' object of metrics")
        if split not in m:
            return None
        return number(m[split].get(key), path, f"{split}.{key}")

    def psnr_by_seed(run_id, seed_list):
        """{seed: mean PSNR over the splits} for the seeds whose run has every split evaluated."""
        found = {}
        for s in seed_list:
            vals = [metric(s, run_id, sp, "psnr") for sp in splits]
            if all(v is not None for v in vals):
                found[s] = statistics.mean(vals)
        return found

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

    lines = [f"# Which camera-times help most: {a.title}, real pool photographs", ""]
    lines.append(f"Seeds {a.seeds}; PSNR in dB on the held-out cameras ({', '.join(splits)}), mean ± standard deviation over the seeds; "
                 "foreground: inside the dataset's foreground masks (– without masks); gain: after a least-squares gain per image. Seconds: selection / training / total of "
                 "the fine-tuning (training alone for the backbone and the dense reference). Seeds: those a row's numbers come from.")
    header = "| run |"
    rule = "|---|"
    for sp in splits:
        header += f" {sp} PSNR | SSIM | foreground | gain |"
        rule += "---|---|---|---|"
    header += " photographs | mean weight | seconds | seeds |"
    rule += "---|---|---|---|"

    def row(run_id, seed_list, label=None):
        cells = f"| {label or run_id} |"
        for sp in splits:
            for key, d in (("psnr", 2), ("ssim", 3), ("psnr_moving", 2), ("psnr_ls_gain", 2)):
                cells += f" {fmt([metric(s, run_id, sp, key) for s in seed_list], d)} |"
        sums = [summary(s, run_id) for s in seed_list]
        views = [float(x["virtual_views"]) for x in sums if x and "virtual_views" in x]
        if run_id.startswith("scratch.") and run_id != "scratch.control":  # trained on the photographs its choice lists
            picks = [load(os.path.join(out, f"s{s}", "choose." + run_id[len("scratch."):], "pool_chosen.json"))
                     for s in seed_list if summary(s, run_id)]
            views = [float(len(p["chosen"])) for p in picks if p]
        weights = [statistics.mean(r["mean_weight"] for r in x["rounds"] if r["views_added"]) for x in sums
                   if x and "rounds" in x and any(r["views_added"] for r in x["rounds"])]
        secs = [seconds(s, run_id) for s in seed_list]
        secs = [x for x in secs if x]
        sel = fmt([x["select"] for x in secs], 0)
        cells += f" {fmt(views, 0)} | {fmt(weights, 3)} | {sel} / {fmt([x['train'] for x in secs], 0)} / {fmt([x['total'] for x in secs], 0)} |"
        cells += f" {','.join(psnr_by_seed(run_id, seed_list)) or '–'} |"
        return cells

    # A strategy whose every pick scored 0 (on a static scene no Gaussian moves, so FillGS's
    # and negative's scores are all 0) was chosen by the pool's order, not by its score.
    def chosen_id(prefix, st, K):
        """Where a protocol's selection is: the main protocol's on the backbone (choose.*), the
        warm start's in its own rounds."""
        return f"choose.{st}.K{K}" if prefix == "scratch." else f"{st}.K{K}"

    def tied(prefix, st, K):
        if st == "random":  # chosen by its draws, not by a score
            return False
        scores = set()
        for s in seeds:
            p = load(os.path.join(out, f"s{s}", chosen_id(prefix, st, K), "pool_chosen.json"))
            if p:
                scores |= {c["score"] for c in p["chosen"]}
        return scores == {0.0}

    def diffs(x, y, sp):
        return [metric(s, x, sp, "psnr") - metric(s, y, sp, "psnr") for s in seeds
                if metric(s, x, sp, "psnr") is not None and metric(s, y, sp, "psnr") is not None]

    def criterion(prefix, K, means, ties, collect=None, protocol=""):
        """FillGS against negative, random and the best baseline: the paired difference per split
        with its 95 % interval (bench/results/README.md, "Criteria, fixed before the runs")."""
        baselines = [b for b in ("random", "interpolation", "fisherrf", "coverage3d", "coverage4d") if b in means and b not in ties]
        common = [s for s in seeds if all(s in means[b] for b in baselines)]
        best = max(baselines, key=lambda b: statistics.mean(means[b][s] for s in common)) if baselines and common else None
        if "fillgs" in ties:
            return ["", "FillGS's picks all scored 0 (no Gaussian moves): its selection is the pool's order, so its differences are not applicable."]
        out_lines = ["", f"FillGS minus each, paired by seed (PSNR, dB): mean ± SD over the seeds, [95 % interval]; **separated** where the "
                         "interval excludes 0. Best baseline (highest mean over the splits and seeds among random, interpolation, FisherRF, "
                         f"coverage3d, coverage4d): {best or '–'}.", "",
                     "| FillGS minus | " + " | ".join(f"{sp}: mean ± SD | 95 % interval" for sp in splits) + " | seeds | seeds for ±0.5 dB |",
                     "|---|" + "---|---|" * len(splits) + "---|---|"]
        for other in ["negative", "random"] + ([best] if best and best != "random" else []):
            label = other + (" (best baseline)" if other == best else "")
            if other in ties:
                out_lines.append(f"| {label} | " + " | ".join("not applicable (every score 0) | –" for _ in splits) + " | – | – |")
                continue
            cells, n, need = [], 0, []
            for sp in splits:
                d = diffs(f"{prefix}fillgs.K{K}", f"{prefix}{other}.K{K}", sp)
                iv = interval(d)
                n = max(n, len(d))
                if iv is None:
                    cells += [fmt(d), "–"]
                    continue
                m, sd, h, nd = iv
                if collect is not None:
                    key = f"{label} ({protocol})"
                    if not collect or collect[-1][0] != key:
                        collect.append((key, {}))
                    collect[-1][1][sp] = (m, m - h, m + h)
                text = f"[{m - h:.2f}, {m + h:.2f}]"
                cells += [f"{m:.2f} ± {sd:.2f}", f"**{text}**" if abs(m) > h else text]
                need.append(nd if h > 0.5 else n)
            out_lines.append(f"| {label} | " + " | ".join(cells) + f" | {n} | {max(need) if need and None not in need else '–'} |")
        return out_lines

    def table(prefix, K, reference_rows, ties):
        """The rows of one protocol at budget K, and each strategy's per-seed mean PSNR over the splits."""
        rows = [header, rule] + reference_rows
        means = {}
        for st in STRATEGIES:
            rid = f"{prefix}{st}.K{K}"
            label = f"{st}.K{K}" + (" (every score 0, pool order)" if st in ties else "")
            rows.append(row(rid, seeds, label))
            per_seed = psnr_by_seed(rid, seeds)
            if per_seed and st not in ties:
                means[st] = per_seed
        return rows, means

    def spread_line(K, means):
        """(the line comparing the best and worst strategy, the best's name), or None without common seeds."""
        common = [s for s in seeds if all(s in v for v in means.values())]
        if not means or not common:
            return None
        m = {k: [v[s] for s in common] for k, v in means.items()}
        best = max(m, key=lambda k: statistics.mean(m[k]))
        worst = min(m, key=lambda k: statistics.mean(m[k]))
        spread = statistics.mean(m[best]) - statistics.mean(m[worst])
        seed_sd = [statistics.stdev(v) for v in m.values() if len(v) > 1]
        sd = statistics.mean(seed_sd) if seed_sd else float("nan")
        return (f"Mean PSNR over the splits, seeds {','.join(common)} (those every strategy has): best {best} "
                f"{statistics.mean(m[best]):.2f} dB, worst {worst} {statistics.mean(m[worst]):.2f} dB, spread {spread:.2f} dB "
                f"against a mean seed spread of {sd:.2f} dB."), best

    chart = []  # (strategy, K, mean gain over the control, its seed spread)

    def chart_gains(prefix, control, K):
        """Each strategy's gain over `control` (mean PSNR over the splits, paired within each seed) onto the chart."""
        for st in STRATEGIES:
            gains = []
            for s in seeds:
                v = [metric(s, f"{prefix}{st}.K{K}", sp, "psnr") for sp in splits]
                c = [metric(s, control, sp, "psnr") for sp in splits]
                if all(x is not None for x in v + c):
                    gains.append(statistics.mean(v) - statistics.mean(c))
            if gains:
                chart.append((st, K, statistics.mean(gains), statistics.stdev(gains) if len(gains) > 1 else 0.0))

    for K in budgets:
        lines += ["", f"## K = {K} camera-times"]
        intervals = []  # FillGS minus negative, random and the best baseline, both protocols
        scratch_rows = any(summary(s, f"scratch.{st}.K{K}") for s in seeds for st in STRATEGIES)
        best_id = None
        if scratch_rows:
            ties = {st for st in STRATEGIES if tied("scratch.", st, K)}
            rows, means = table("scratch.", K, [row("dense", ["1"], "dense reference (training + every pool photograph)"),
                                                row("backbone", seeds, "backbone (the model every strategy chooses on)"),
                                                row("scratch.control", seeds, "training cameras alone")], ties)
            lines += ["", "### Trained from scratch (the main protocol)", "",
                      "Each strategy chooses the K camera-times on the seed's backbone in one greedy round (each chosen one counted as an "
                      "observation before the next); a model is then trained on the training cameras and the chosen photographs with the "
                      "dense reference's settings, from the seed's backbone's initial points.", ""] + rows + criterion("scratch.", K, means, ties, intervals, "from scratch")
            sl = spread_line(K, means)
            if sl:
                lines += ["", sl[0]]
                best_id = f"scratch.{sl[1]}.K{K}"
            chart_gains("scratch.", "scratch.control", K)
        # The warm start's control alone (made for another budget) is no table at this budget.
        warm_rows = any(summary(s, f"{st}.K{K}") for s in seeds for st in STRATEGIES)
        if not warm_rows:
            lines += ["", f"### Warm start (second protocol)", "", f"No warm-start run at K = {K} for these seeds."]
        else:
            ties = {st for st in STRATEGIES if tied("", st, K)}
            rows, means = table("", K, [row("backbone", seeds), row("control", seeds, "control (no photographs added)")], ties)
            for w in ("fillgs", "exploregs"):
                rid = f"fillgs.K{K}.w-{w}"
                if any(summary(s, rid) for s in seeds):
                    rows.append(row(rid, seeds))
            lines += ["", "### Warm start: the backbone fine-tuned with the photographs (second protocol)", "",
                      "The selection runs here, in three rounds, each choosing from the current model; the photographs are added at their real poses.",
                      ""] + rows + criterion("", K, means, ties, intervals, "warm start")
            sl = spread_line(K, means)
            if sl:
                lines += ["", sl[0]]
                best_id = best_id or f"{sl[1]}.K{K}"
            if not scratch_rows:
                chart_gains("", "control", K)
        if intervals and write_interval_chart(out, f"intervals_K{K}", intervals, splits,
                                              f"{a.title}, K = {K}: FillGS minus each, 95 % intervals (filled: excludes 0)"):
            lines += ["", f"![FillGS minus each, K = {K}, 95 % intervals](intervals_K{K}.png)"]
        if best_id:
            lines += ["", f"best at K={K}: {best_id}"]
        # What each strategy chose, per seed: its (camera, frame) pairs (the main protocol's
        # selection where it ran, else the warm start's).
        pick = "scratch." if scratch_rows else ""
        chosen = {}
        for st in STRATEGIES:
            for s in seeds:
                p = load(os.path.join(out, f"s{s}", chosen_id(pick, st, K), "pool_chosen.json"))
                if p:
                    chosen.setdefault(st, {})[s] = {(c["camera"], c["frame"]) for c in p["chosen"]}
        # How spread each strategy's choices are: distinct cameras and frames (mean over the seeds).
        if chosen:
            def distinct(st, part):
                return statistics.mean(len({pair[part] for pair in picks}) for picks in chosen[st].values())
            lines += ["", f"Distinct pool cameras / frames among the {K} camera-times chosen (mean over the seeds): " +
                      "; ".join(f"{st} {distinct(st, 0):.1f} / {distinct(st, 1):.1f}" for st in STRATEGIES if st in chosen) + "."]
        if len(chosen) > 1:
            names = [st for st in STRATEGIES if st in chosen]
            lines += ["", f"Share of camera-times two strategies both chose at K = {K} (|A ∩ B| / K, mean over the seeds):", "",
                      "| | " + " | ".join(names) + " |", "|---|" + "---|" * len(names)]
            for x in names:
                cells = []
                for y in names:
                    share = [len(chosen[x][s] & chosen[y][s]) / max(1, len(chosen[x][s])) for s in seeds if s in chosen[x] and s in chosen[y]]
                    cells.append(f"{statistics.mean(share):.2f}" if share else "–")
                lines.append(f"| {x} | " + " | ".join(cells) + " |")
            lines += ["", f"What each strategy chose (camera × frame, seed {seeds[0]}; each run's own picture and list are "
                          f"s{seeds[0]}/{chosen_id(pick, '<strategy>', K)}/pool_chosen.png and .json): ![chosen](chosen_K{K}_s{seeds[0]}.png)"]
    if chart and write_chart(out, chart, budgets, a.title):
        lines += ["", "Gain over the control of the main protocol (mean PSNR over the splits, paired within each seed; bars: mean, "
                      "whiskers: ± standard deviation over the seeds):", "", "![gain over the control](gain.png)"]
    lines += ["", "![ground truth | backbone | best strategy | FillGS (the main protocol's models)](compare.png)", ""]
    write_atomic(os.path.join(out, "results.md"), "\n".join(lines))
    sys.stdout.write("\n".join(lines))
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except ReportError as e:
        sys.stderr.write(f"pool_select_report: {e}\n")
        sys.exit(1)
