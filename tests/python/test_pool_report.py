"""bench/pool_select_report.py on a folder of runs with known PSNRs: the paired differences'
means, SDs and 95 % intervals against values worked out by hand (t(0.975, 2) = 4.302653,
the printed table's), the "separated" mark only where the interval excludes 0, and the
interval chart's CSV. Needs no fillgs build; run by CTest with the module's tests."""
import json
import math
import os
import subprocess
import sys

SOURCE = os.environ.get("FILLGS_SOURCE", os.path.join(os.path.dirname(__file__), "..", ".."))
STRATEGIES = ["fillgs", "random", "negative", "interpolation", "fisherrf", "coverage3d", "coverage4d"]
T975_DF2 = 4.302653


def write(path, obj):
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, "w") as f:
        json.dump(obj, f)


def make_folder(root):
    """Three seeds of the main protocol at K = 30: FillGS - negative is 0.1, 0.2, 0.3 dB at the
    near cameras and 0 far; FillGS - random 1.0, 1.1, 1.2 near; every other strategy 2 dB below
    FillGS (so random is the best baseline)."""
    base = {1: 16.0, 2: 16.5, 3: 15.5}
    offset = {"fillgs": 0.0, "interpolation": -2.0, "fisherrf": -2.0, "coverage3d": -2.0, "coverage4d": -2.0}
    for s, b in base.items():
        k = s - 1  # seed index
        near = {"fillgs": b, "negative": b - (0.1, 0.2, 0.3)[k], "random": b - (1.0, 1.1, 1.2)[k]}
        for st in STRATEGIES:
            n = near.get(st, b + offset.get(st, 0.0))
            f = b + (0.0 if st in ("fillgs", "negative", "random") else -2.0)
            d = os.path.join(root, f"s{s}", f"scratch.{st}.K30")
            write(os.path.join(d, "summary.json"), {"seconds": 100.0})
            write(os.path.join(d, "eval_near", "metrics.json"), {"near": {"psnr": n, "ssim": 0.5, "psnr_ls_gain": n}})
            write(os.path.join(d, "eval_far", "metrics.json"), {"far": {"psnr": f, "ssim": 0.5, "psnr_ls_gain": f}})
            write(os.path.join(root, f"s{s}", f"choose.{st}.K30", "pool_chosen.json"),
                  {"chosen": [{"camera": "9", "frame": j, "score": 0.5 if st != "random" else 0.0} for j in range(30)]})
        for rid in ("scratch.control", "backbone"):
            d = os.path.join(root, f"s{s}", rid)
            write(os.path.join(d, "summary.json"), {"seconds": 100.0})
            for sp in ("near", "far"):
                write(os.path.join(d, f"eval_{sp}", "metrics.json"), {sp: {"psnr": b - 1, "ssim": 0.5, "psnr_ls_gain": b}})


def test_intervals_equal_hand_worked_values(tmp_path):
    root = str(tmp_path / "pool")
    make_folder(root)
    r = subprocess.run([sys.executable, os.path.join(SOURCE, "bench", "pool_select_report.py"), root, "--seeds", "1,2,3", "--budgets", "30",
                        "--splits", "near,far"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    md = open(os.path.join(root, "results.md")).read()
    h = T975_DF2 * 0.1 / math.sqrt(3)  # SD 0.1 over three seeds
    # FillGS - negative near: 0.20 +- 0.10, [0.20 - h, 0.20 + h] = [-0.05, 0.45]: not separated.
    neg = next(line for line in md.splitlines() if line.startswith("| negative |"))
    assert "0.20 ± 0.10" in neg and f"[{0.2 - h:.2f}, {0.2 + h:.2f}]" in neg and "**[" not in neg.split("|")[3]
    # FillGS - random near: 1.10 +- 0.10, separated; far 0.00 +- 0.00.
    rnd = next(line for line in md.splitlines() if line.startswith("| random (best baseline) |"))
    assert "1.10 ± 0.10" in rnd and f"**[{1.1 - h:.2f}, {1.1 + h:.2f}]**" in rnd
    # The chart's CSV holds the same intervals, separated only for random at the near cameras.
    rows = [line.split(",") for line in open(os.path.join(root, "intervals_K30.csv")).read().splitlines()[1:]]
    got = {(row[6].strip('"'), row[7]): (float(row[2]), float(row[3]), float(row[4]), int(row[5])) for row in rows}
    m, lo, hi, sep = got[("negative (from scratch)", "near")]
    assert math.isclose(m, 0.2, abs_tol=1e-6) and math.isclose(lo, 0.2 - h, abs_tol=1e-5) and math.isclose(hi, 0.2 + h, abs_tol=1e-5) and sep == 0
    m, lo, hi, sep = got[("random (best baseline) (from scratch)", "near")]
    assert math.isclose(m, 1.1, abs_tol=1e-6) and sep == 1
    assert got[("random (best baseline) (from scratch)", "far")][3] == 0
    assert "![FillGS minus each, K = 30, 95 % intervals](intervals_K30.png)" in md or not os.path.exists(os.path.join(root, "intervals_K30.png"))


def test_main_protocol_rows_without_a_warm_start(tmp_path):
    """The main protocol's table carries the backbone (mean of 15.0, 15.5, 14.5 = 15.00 dB) and
    each strategy's photographs from its choice (30); with no warm-start run the second protocol
    is one line, not a table of dashes."""
    root = str(tmp_path / "pool")
    make_folder(root)
    r = subprocess.run([sys.executable, os.path.join(SOURCE, "bench", "pool_select_report.py"), root, "--seeds", "1,2,3", "--budgets", "30",
                        "--splits", "near,far"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    md = open(os.path.join(root, "results.md")).read().splitlines()
    backbone = next(line for line in md if line.startswith("| backbone (the model every strategy chooses on) |"))
    assert backbone.split("|")[2].strip() == "15.00 ± 0.50"
    fillgs = next(line for line in md if line.startswith("| fillgs.K30 |"))
    assert fillgs.split("|")[10].strip() == "30 ± 0"
    assert "No warm-start run at K = 30 for these seeds." in md
    assert not any(line.startswith("| control (no photographs added) |") for line in md)


def test_warm_start_control_alone_is_no_table(tmp_path):
    """A warm-start control (it serves every budget) with warm-start runs at K = 30 only: K = 30
    gets the warm-start table, K = 10 one line, not a table of dashes under a control row."""
    root = str(tmp_path / "pool")
    make_folder(root)
    for s in (1, 2, 3):
        for rid in ("control", "fillgs.K30", "random.K30"):
            d = os.path.join(root, f"s{s}", rid)
            write(os.path.join(d, "summary.json"), {"seconds": 100.0, "pool_added": 0 if rid == "control" else 30})
            for sp in ("near", "far"):
                write(os.path.join(d, f"eval_{sp}", "metrics.json"), {sp: {"psnr": 15.0, "ssim": 0.5, "psnr_ls_gain": 15.0}})
    r = subprocess.run([sys.executable, os.path.join(SOURCE, "bench", "pool_select_report.py"), root, "--seeds", "1,2,3", "--budgets", "10,30",
                        "--splits", "near,far"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    md = open(os.path.join(root, "results.md")).read().splitlines()
    assert "No warm-start run at K = 10 for these seeds." in md
    assert "No warm-start run at K = 30 for these seeds." not in md
    assert not any(line.startswith("| fillgs.K10 |") for line in md)
    assert sum(line.startswith("| control (no photographs added) |") for line in md) == 1
    assert any(line.startswith("| fillgs.K30 | 15.00 ± 0.00 |") for line in md)


def report(root, *args):
    return subprocess.run([sys.executable, os.path.join(SOURCE, "bench", "pool_select_report.py"), root, "--budgets", "30", "--splits", "near,far",
                           *args], capture_output=True, text=True)


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
