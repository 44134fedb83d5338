"""bench/pool_select_report.py on a folder of runs with known PSNRs: the paired differences'
means, SDs and 95 % intervals against values worked out by hand (t(0.975, 2) = 4.302653,
the printed table's), the "separated" mark only where the interval excludes 0, the positive
control's verdict per split, the per-camera table, the window per seed, the draws per chosen
photograph and the interval chart's CSV; and bench/pool_positive.py's choice on a rig laid out
by hand. Needs no fillgs build; run by CTest with the module's tests."""
import json
import math
import os
import subprocess
import sys

SOURCE = os.environ.get("FILLGS_SOURCE", os.path.join(os.path.dirname(__file__), "..", ".."))
STRATEGIES = ["fillgs", "random", "negative", "interpolation", "fisherrf", "coverage3d", "coverage4d", "positive"]
T975_DF2 = 4.302653
COLUMNS = ["camera", "frame", "psnr", "ssim", "psnr_ls_gain", "psnr_affine", "moving_squared_error", "moving_pixels"]


def write(path, obj):
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, "w") as f:
        json.dump(obj, f)


def split_metrics(affine, cameras):
    """A split's metrics.json object: affine PSNR `affine` (raw 2 dB lower), its per-view rows two
    frames per camera, the first camera 0.5 dB above the split's mean and the second 0.5 below."""
    rows = []
    for k, c in enumerate(cameras):
        v = affine + (0.5 if k == 0 else -0.5)
        rows += [[c, f, v - 2, 0.5, None, v, 1.0, 10] for f in (0, 1)]
    return {"psnr": affine - 2, "ssim": 0.5, "psnr_moving": affine - 3, "psnr_affine": affine, "views": len(rows),
            "per_view_columns": COLUMNS, "per_view": rows}


def run(root, seed, rid, near, far, draws=None):
    d = os.path.join(root, f"s{seed}", rid)
    write(os.path.join(d, "summary.json"), {"seconds": 100.0, "gaussians": 1000, "moving_gaussians": 10,
                                            "draws": {"per_view": draws or [["3", 0, 25]]}})
    write(os.path.join(d, "eval_near", "metrics.json"), {"near": split_metrics(near, ["18", "2"])})
    write(os.path.join(d, "eval_far", "metrics.json"), {"far": split_metrics(far, ["29", "11"])})


def make_folder(root):
    """Three seeds at K = 30 (affine PSNR; raw PSNR 2 dB lower everywhere):
    FillGS - negative near 0.1, 0.2, 0.3, far 0; FillGS - random near 1.0, 1.1, 1.2, far 0.5
    each seed; the other four strategies 2 dB below FillGS; the positive control above random
    by 0.5, 0.7, 0.9 near (separated) and 0.1, -0.1, 0 far (not); the dense reference 1 dB above
    FillGS's base and the control 1 dB below (a window of 2 dB)."""
    base = {1: 16.0, 2: 16.5, 3: 15.5}
    for s, b in base.items():
        k = s - 1
        near = {"fillgs": b, "negative": b - (0.1, 0.2, 0.3)[k], "random": b - (1.0, 1.1, 1.2)[k]}
        far = {"fillgs": b, "negative": b, "random": b - 0.5}
        near["positive"] = near["random"] + (0.5, 0.7, 0.9)[k]
        far["positive"] = far["random"] + (0.1, -0.1, 0.0)[k]
        for st in STRATEGIES:
            picks = [{"camera": "9", "frame": j, "score": 0.5 if st != "random" else 0.0} for j in range(30)]
            write(os.path.join(root, f"s{s}", f"choose.{st}.K30", "pool_chosen.json"), {"chosen": picks})
            draws = [["9", j, 25] for j in range(30)] + [["3", 0, 25]]
            run(root, s, f"scratch.{st}.K30", near.get(st, b - 2), far.get(st, b - 2), draws)
        run(root, s, "scratch.control", b - 1, b - 1)
        run(root, s, "backbone", b - 1, b - 1)
        run(root, s, "dense", b + 1, b + 1)
    for rid, v in (("scratch.control", 20.0), ("backbone.curriculum", 20.5)):
        write(os.path.join(root, "s1", rid, "eval_train", "metrics.json"), {"train": split_metrics(v, ["3", "22"])})
    run(root, 1, "backbone.curriculum", 14.0, 14.0)


def report(root, *args):
    return subprocess.run([sys.executable, os.path.join(SOURCE, "bench", "pool_select_report.py"), root, "--budgets", "30", "--splits", "near,far",
                           *args], capture_output=True, text=True)


def line(md, start):
    return next(x for x in md.splitlines() if x.startswith(start))


def test_intervals_equal_hand_worked_values(tmp_path):
    root = str(tmp_path / "pool")
    make_folder(root)
    r = report(root, "--seeds", "1,2,3")
    assert r.returncode == 0, r.stderr
    md = open(os.path.join(root, "results.md")).read()
    h = T975_DF2 * 0.1 / math.sqrt(3)  # SD 0.1 over three seeds
    # FillGS - negative near: 0.20 +- 0.10, [0.20 - h, 0.20 + h] = [-0.05, 0.45]: not separated.
    neg = line(md, "| FillGS minus negative |")
    assert "0.20 ± 0.10" in neg and f"[{0.2 - h:.2f}, {0.2 + h:.2f}]" in neg and "**[" not in neg.split("|")[3]
    # FillGS - random near: 1.10 +- 0.10, separated; far 0.50 +- 0.00, separated.
    rnd = line(md, "| FillGS minus random |")
    assert "1.10 ± 0.10" in rnd and f"**[{1.1 - h:.2f}, {1.1 + h:.2f}]**" in rnd and "**[0.50, 0.50]**" in rnd
    # Every one of the six comparators printed, twice (affine, then raw PSNR: the same differences here).
    for other in ("negative", "random", "interpolation", "fisherrf", "coverage3d", "coverage4d"):
        assert sum(x.startswith(f"| FillGS minus {other} |") for x in md.splitlines()) == 2
    assert "best" not in md.lower()
    # The chart's CSV holds the same intervals.
    rows = [x.split(",") for x in open(os.path.join(root, "intervals_K30.csv")).read().splitlines()[1:]]
    got = {(row[6].strip('"'), row[7]): (float(row[2]), float(row[3]), float(row[4]), int(row[5])) for row in rows}
    m, lo, hi, sep = got[("FillGS minus negative", "near")]
    assert math.isclose(m, 0.2, abs_tol=1e-6) and math.isclose(lo, 0.2 - h, abs_tol=1e-5) and math.isclose(hi, 0.2 + h, abs_tol=1e-5) and sep == 0
    assert got[("FillGS minus random", "near")][3] == 1


def test_positive_control_verdict_per_split(tmp_path):
    """positive - random near: 0.70 +- 0.20, h = 4.302653 * 0.2 / sqrt(3) = 0.497: separated; far
    0.00 +- 0.10: not, and the report says the instrument cannot judge there."""
    root = str(tmp_path / "pool")
    make_folder(root)
    r = report(root, "--seeds", "1,2,3")
    assert r.returncode == 0, r.stderr
    md = open(os.path.join(root, "results.md")).read()
    pos = line(md, "| positive control minus random |")
    h = T975_DF2 * 0.2 / math.sqrt(3)
    assert "0.70 ± 0.20" in pos and f"**[{0.7 - h:.2f}, {0.7 + h:.2f}]**" in pos and "0.00 ± 0.10" in pos
    assert "does not separate from random on the far split: there the instrument cannot judge" in md
    # Without a positive control run, the report says nothing can be ranked.
    import shutil
    for s in (1, 2, 3):
        shutil.rmtree(os.path.join(root, f"s{s}", "scratch.positive.K30"))
    r = report(root, "--seeds", "1,2,3")
    assert r.returncode == 0, r.stderr
    assert "No positive control at K = 30" in open(os.path.join(root, "results.md")).read()


def test_positive_control_behind_random_is_not_separation(tmp_path):
    """positive - random far: -0.3, -0.5, -0.7 (mean -0.50, SD 0.20, h = 0.497: the interval
    [-0.997, -0.003] excludes 0 below it). That is a positive control doing worse than random,
    not an instrument telling a better selection apart: the far split is listed as unable to judge."""
    root = str(tmp_path / "pool")
    make_folder(root)
    for s, delta in ((1, -0.3), (2, -0.5), (3, -0.7)):
        rnd = json.load(open(os.path.join(root, f"s{s}", "scratch.random.K30", "eval_far", "metrics.json")))["far"]["psnr_affine"]
        near = json.load(open(os.path.join(root, f"s{s}", "scratch.positive.K30", "eval_near", "metrics.json")))["near"]["psnr_affine"]
        run(root, s, "scratch.positive.K30", near, rnd + delta, [["9", j, 25] for j in range(30)] + [["3", 0, 25]])
    r = report(root, "--seeds", "1,2,3")
    assert r.returncode == 0, r.stderr
    md = open(os.path.join(root, "results.md")).read()
    h = T975_DF2 * 0.2 / math.sqrt(3)
    assert f"**[{-0.5 - h:.2f}, {-0.5 + h:.2f}]**" in line(md, "| positive control minus random |")
    assert "does not separate from random on the far split: there the instrument cannot judge" in md
    assert "On the far split the positive control is behind random" in md
    assert "separates from random on every split" not in md


def test_per_camera_window_draws_and_curriculum(tmp_path):
    root = str(tmp_path / "pool")
    make_folder(root)
    r = report(root, "--seeds", "1,2,3")
    assert r.returncode == 0, r.stderr
    md = open(os.path.join(root, "results.md")).read()
    # Per camera: FillGS's near camera 18 is 0.5 above its split (16.5 over the seeds' 16.0, 16.5, 15.5 + 0.5).
    header = line(md, "| run | near 2 | near 18 | far 11 | far 29 |")
    assert header
    fill = line(md, "| fillgs |").split("|")
    assert [c.strip() for c in fill[1:6]] == ["fillgs", "15.50", "16.50", "15.50", "16.50"]
    # The window per seed: dense (b + 1) minus control (b - 1).
    for s, b in ((1, 16.0), (2, 16.5), (3, 15.5)):
        assert line(md, f"| {s} | {b + 1:.2f} | {b - 1:.2f} | +2.00 |")
    # Every chosen photograph drawn 25 times; 30 photographs.
    row = line(md, "| fillgs.K30 |").split("|")
    assert row[10].strip() == "30 ± 0" and row[11].strip() == "25.0 ± 0.0"
    # The curriculum's table: the training cameras' affine PSNR of both runs.
    assert line(md, "| every photograph equally likely | 20.00 |") and line(md, "| time curriculum | 20.50 |")


def test_a_chosen_photograph_missing_from_the_draws_is_named(tmp_path):
    root = str(tmp_path / "pool")
    make_folder(root)
    path = os.path.join(root, "s2", "scratch.random.K30", "summary.json")
    write(path, {"seconds": 100.0, "draws": {"per_view": [["3", 0, 25]]}})
    r = report(root, "--seeds", "1,2,3")
    assert r.returncode == 1 and path in r.stderr and "a chosen photograph is not among the views it trained on" in r.stderr, r.stderr


def test_positive_control_choice_by_hand(tmp_path):
    """Pool cameras on a line at x = 0, 1, 2, 3; judged: near n at x = 0.9, far f at x = 3.2.
    K = 4 over 4 frames: near, far, near, far at frames 0, 1, 2, 3 -> pool 1, 3, 1, 3."""
    def transforms(path, cams):
        write(path, {"frames": [{"file_path": f"{c}/000000.jpg", "transform_matrix": [[1, 0, 0, x], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]}
                                for c, x in cams]})
    rig, held, out = str(tmp_path / "rig.json"), str(tmp_path / "held.json"), str(tmp_path / "c" / "pool_chosen.json")
    transforms(rig, [("p0", 0.0), ("p1", 1.0), ("p2", 2.0), ("p3", 3.0)])
    transforms(held, [("n", 0.9), ("f", 3.2)])
    cmd = [sys.executable, os.path.join(SOURCE, "bench", "pool_positive.py"), "--rig", rig, "--held-out", held, "--splits", "n:f",
           "--pool", "p0,p1,p2,p3", "--frames", "4"]
    r = subprocess.run(cmd + ["--budget", "4", "--out", out], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    got = [(c["camera"], c["frame"]) for c in json.load(open(out))["chosen"]]
    assert got == [("p1", 0), ("p3", 1), ("p1", 2), ("p3", 3)]
    # K = 8 over 2 frames: frames floor((2i + 1) * 2 / 16) = 0,0,0,0,1,1,1,1; each judged camera's
    # nearest free pool camera at that frame: n -> p1, p0; f -> p3, p2.
    r = subprocess.run(cmd[:-1] + ["2", "--budget", "8", "--out", out], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    got = [(c["camera"], c["frame"]) for c in json.load(open(out))["chosen"]]
    assert got == [("p1", 0), ("p3", 0), ("p0", 0), ("p2", 0), ("p1", 1), ("p3", 1), ("p0", 1), ("p2", 1)]
    r = subprocess.run(cmd + ["--budget", "17", "--out", out], capture_output=True, text=True)
    assert r.returncode == 1 and "--budget 17 camera-times from 4 pool cameras x 4 frames" in r.stderr


def test_a_title_with_quotes_and_commands_stays_a_title(tmp_path):
    """The title is the user's text in gnuplot's scripts: a quote ended the string (a 0-byte
    chart) and a line break or backquote ran what followed as gnuplot's (or a shell's) command."""
    root = str(tmp_path / "pool")
    make_folder(root)
    title = "Bob's kitchen\nsystem \"touch PWNED\" `touch PWNED2`"
    r = report(root, "--seeds", "1,2,3", "--title", title)
    assert r.returncode == 0, r.stderr
    for gp in ("gain.gp", "intervals_K30.gp"):
        script = open(os.path.join(root, gp)).read()
        assert "`" not in script and "\nsystem" not in script and "Bob''s kitchen" in script
    assert not os.path.exists(os.path.join(root, "PWNED")) and not os.path.exists(os.path.join(root, "PWNED2"))
    if subprocess.run(["which", "gnuplot"], capture_output=True).returncode == 0:
        assert os.path.getsize(os.path.join(root, "gain.png")) > 1000


def test_a_damaged_metrics_file_is_named(tmp_path):
    root = str(tmp_path / "pool")
    make_folder(root)
    bad = os.path.join(root, "s2", "scratch.random.K30", "eval_near", "metrics.json")
    for text, words in (('{"near": {"psnr": 1', "not a JSON file"), ('{"near": {"psnr": "16.1"}}', 'near.psnr is "16.1"'),
                        ('{"near": {"psnr": NaN}}', "near.psnr is NaN")):
        with open(bad, "w") as f:
            f.write(text)
        r = report(root, "--seeds", "1,2,3")
        assert r.returncode == 1 and "Traceback" not in r.stderr, r.stderr
        assert r.stderr.strip().splitlines() == [r.stderr.strip()] and bad in r.stderr and words in r.stderr, r.stderr


def test_a_seed_given_twice_is_refused(tmp_path):
    """--seeds 1,1 paired a run with itself: a zero-width interval printed as "separated"."""
    root = str(tmp_path / "pool")
    make_folder(root)
    r = report(root, "--seeds", "1,1")
    assert r.returncode == 2 and "--seeds 1,1: 1 is given twice" in r.stderr, r.stderr
    assert not os.path.exists(os.path.join(root, "results.md"))


def test_damaged_summaries_and_choices_are_named(tmp_path):
    root = str(tmp_path / "pool")
    make_folder(root)
    cases = ((os.path.join(root, "s1", "scratch.random.K30", "summary.json"), '{"seconds": 100.0, "rounds": 5}', "'rounds' is not a list"),
             (os.path.join(root, "s1", "scratch.random.K30", "summary.json"), '{"seconds": "a while"}', 'seconds is "a while"'),
             (os.path.join(root, "s2", "choose.negative.K30", "pool_chosen.json"), '{"chosen": [{"camera": "9"}]}', "chosen[0] lacks camera, frame or score"))
    for path, text, words in cases:
        before = open(path).read()
        with open(path, "w") as f:
            f.write(text)
        r = report(root, "--seeds", "1,2,3")
        assert r.returncode == 1 and "Traceback" not in r.stderr and path in r.stderr and words in r.stderr, r.stderr
        with open(path, "w") as f:
            f.write(before)


def test_pool_script_refuses_a_list_naming_an_item_twice(tmp_path):
    for flag, value, twice in (("--seeds", "1,2,1", "1"), ("--strategies", "random,random", "random")):
        r = subprocess.run(["bash", os.path.join(SOURCE, "bench", "pool_select.sh"), flag, value, "--smoke", str(tmp_path / "pool")],
                           capture_output=True, text=True, cwd=SOURCE)
        assert r.returncode == 1 and f"pool_select: {flag} {value}: {twice} is given twice" in r.stderr, r.stderr
        assert not os.path.exists(tmp_path / "pool")
