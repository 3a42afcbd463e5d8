"""Fuzzing the DISCON library's input file (issue 30, defect 3): mutated `.IN` files,
deterministic seeds, through the compiled library loaded with ctypes, the way ServoDyn
calls it.

Whatever the mutation, every call either returns aviFAIL = 0 with every demand (#42-#45,
#47) a finite float, or aviFAIL = -1 with a message in avcMSG, written only within the
#49 bytes the host gives (its NUL included; a canary fills the rest of the buffer); and the
process survives (each batch runs in a process of its own: a crash fails the test naming
its case). Where a mutation sets one value, the library's verdict on it is wtftc's own:
refused naming that parameter exactly when wtftc.config (the layout's valid ranges and its
cross-checks) or, for the FDI's own constants, discon_checks.checks refuses it.

500 cases on two libraries (physical: a Cp file and every group; paper: no Cp file, the
control sign), each built once for the module at -O0.
"""

from __future__ import annotations

import json
import math
import os
import random
import re
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest

from wtftc import config
from wtftc.artefacts import layout as lay
from wtftc.errors import ConfigError
from wtftc.export import discon, discon_checks

ROOT = Path(__file__).resolve().parent.parent
RATED = (1.26711, 1.26711 * 97.0)
#: cases per library, in batches of at most BATCH (one process each)
CASES = {"physical": 400, "paper": 100}
BATCH = 200
#: what a value mutation writes: the edges of numbers, degrees for radians, signs, and
#: tokens that are no number
NUMBERS = ["0", "-0.0", "-1", "1", "90", "-90", "180", "1e-300", "5e-324", "1e300",
           "-1e300", "1.7976931348623157e308", "2", "0.5", "1e9", "-1e-9"]
WORDS = ["nan", "inf", "-inf", "1e400", "0x1p-3", "", "abc", "1,5", "1.0.0", "1.5e", "--1",
         "1.0 2.0", "1.0abc", "\"1.0\"", "Ω"]
#: #49 values: ServoDyn's 1025 (half of the cases: whole messages, whose verdict is
#: checked), ROSCO's 500 ... down to no room at all
CAPACITIES = [1025] * 9 + [500, 256, 80, 16, 2, 1, 0, -5, float("nan")]


@pytest.fixture(scope="module")
def libs(tmp_path_factory) -> dict[str, Path]:
    """The two libraries, exported once (in parallel: the compilers run side by side)."""
    base = tmp_path_factory.mktemp("discon_fuzz")
    with ThreadPoolExecutor(2) as pool:
        done = {c: pool.submit(discon.export, c, base / c, opt="-O0") for c in CASES}
    return {c: f.result() for c, f in done.items()}


def _values(lines: list[str]) -> dict[str, tuple[int, str]]:
    """Each parameter line of a .IN by name: (line index, value token)."""
    out = {}
    for k, ln in enumerate(lines):
        words = ln.split("!")[0].split()
        if len(words) == 2 and words[0] != discon.CP_KEY:
            out[words[0]] = (k, words[1])
    return out


def _set(lines: list[str], name: str, token: str) -> list[str]:
    k, _ = _values(lines)[name]
    return [*lines[:k], f"{name} {token}  ! fuzzed", *lines[k + 1:]]


def _mutate(lines: list[str], rng: random.Random, folder: Path) -> tuple[bytes, tuple | None]:
    """One mutation of the .IN's lines: its bytes, and (name, token) when it set one value
    and did nothing else."""
    names = list(_values(lines))
    op = rng.randrange(-3, 12)  # half of them set one value
    if op <= 3:  # one value: a number at an edge, or a token that is none
        name = rng.choice(names)
        token = rng.choice(NUMBERS if op <= 2 else WORDS)
        return ("\n".join(_set(lines, name, token)) + "\n").encode(), (name, token)
    if op == 4:  # one value scaled (plausible values, which reach the cross-checks)
        name = rng.choice(names)
        v = float(_values(lines)[name][1]) * rng.choice([-1.0, 0.0, 0.5, 1.5, 10.0, 1e6])
        return ("\n".join(_set(lines, name, repr(v))) + "\n").encode(), (name, repr(v))
    ls = list(lines)
    if op == 5:  # a line deleted, duplicated or two swapped
        k, j = rng.randrange(len(ls)), rng.randrange(len(ls))
        kind = rng.randrange(3)
        if kind == 0:
            del ls[k]
        elif kind == 1:
            ls.insert(j, ls[k])
        else:
            ls[k], ls[j] = ls[j], ls[k]
    elif op == 6:  # two values exchanged
        a, b = rng.sample(names, 2)
        va, vb = _values(ls)[a][1], _values(ls)[b][1]
        ls = _set(_set(ls, a, vb), b, va)
    elif op == 7:  # the Cp file named otherwise
        perf = [k for k, ln in enumerate(ls) if ln.startswith(discon.CP_KEY)]
        special = folder / f"fifo_{rng.randrange(10**6)}"
        if not special.exists():
            os.mkfifo(special)
        name = rng.choice(['"missing.txt"', '""', '"unterminated', "", '"/dev/zero"',
                           '"."', f'"{special}"', '"' + "x" * 3000 + '"', "'single.txt'",
                           '"/dev/null"'])
        line = f"{discon.CP_KEY} {name}"
        if perf:
            ls[perf[0]] = line
        else:
            ls.insert(rng.randrange(len(ls) + 1), line)
    elif op == 8:  # a long line, a comment or not
        k = rng.randrange(len(ls))
        ls[k] = ls[k] + rng.choice(["", " ! "]) + "y" * rng.choice([600, 5000, 20000])
    elif op == 9:  # other line endings and spacing (to be accepted)
        sep = rng.choice(["\r\n", "\n\n", "\t"])
        text = ("\r\n".join(ls) if sep == "\r\n" else "\n".join(
            ln.replace(" ", sep) if sep == "\t" else ln for ln in ls)
            if sep != "\n\n" else "\n\n".join(ls))
        return text.encode(), None
    raw = bytearray(("\n".join(ls) + "\n").encode())
    if op == 10:  # bytes flipped, inserted (NUL, invalid UTF-8) or the file cut short
        for _ in range(rng.randint(1, 8)):
            kind, at = rng.randrange(3), rng.randrange(len(raw))
            if kind == 0:
                raw[at] = rng.randrange(256)
            elif kind == 1:
                raw[at:at] = bytes(rng.choice([[0], [0xff, 0xfe], [10], [33], [0xc3]]))
            else:
                del raw[at:]
                break
    elif op == 11:  # nothing, or noise
        raw = bytearray(rng.choice([b"", b"\n", bytes(rng.randrange(256) for _ in range(500))]))
    return bytes(raw), None


def _cases(controller: str, lib_dir: Path, folder: Path, n: int, seed: int) -> list[dict]:
    """``n`` cases: mutated .IN files beside the library (its Cp file then resolves), a
    few special paths as the input file, each with a #49 and a call sequence: a first
    call, three running calls, a final one."""
    rng = random.Random(seed)
    lines = (lib_dir / f"wtftc_{controller}.IN").read_text().splitlines()
    fifo = folder / "input_fifo"
    os.mkfifo(fifo)
    special = [str(fifo), "/dev/zero", str(folder), str(folder / "none.IN"), "/dev/null"]
    out = []
    for k in range(n):
        if k < len(special):
            infile, set_one = special[k], None
        else:
            data, set_one = _mutate(lines, rng, folder)
            path = lib_dir / f"fuzz_{seed}_{k}.IN"
            path.write_bytes(data)
            infile = str(path)
        w = rng.choice([1.0, 0.9, 1.1, 0.5, 1.5])
        calls = [[0, 0.0, RATED[0] * w, RATED[1] * w, 0.2, 0.2, 0.2]]
        calls += [[1, 0.01 * j, RATED[0] * w, RATED[1] * w, 0.2 + 0.01 * j, 0.2, 0.19]
                  for j in range(1, 4)]
        calls.append([-1, 0.04, *RATED, 0.2, 0.2, 0.2])
        out.append({"infile": infile, "capacity": rng.choice(CAPACITIES), "calls": calls,
                    "set_one": set_one})
    return out


def _run_batch(lib: Path, cases: list[dict], folder: Path, tag: str) -> list[dict]:
    """The cases in a process of their own: every case's result, or a failure naming the
    case the process died in."""
    cases_file, results = folder / f"{tag}.json", folder / f"{tag}.jsonl"
    cases_file.write_text(json.dumps(cases))
    done = subprocess.run([sys.executable, str(ROOT / "tests" / "discon_host.py"), str(lib),
                           str(cases_file), str(results)], cwd=ROOT, capture_output=True,
                          text=True, timeout=120)
    rows = [json.loads(ln) for ln in results.read_text().splitlines()] \
        if results.exists() else []
    got = {r["case"]: r["calls"] for r in rows if "calls" in r}
    started = [r["case"] for r in rows if r.get("start")]
    assert done.returncode == 0 and len(got) == len(cases), (
        f"{tag}: the host process ended with {done.returncode} in case "
        f"{started[-1] if started else None} ({cases[started[-1]]['infile'] if started else ''})"
        f": {done.stderr[-800:]}")
    return [got[k] for k in range(len(cases))]


def _verdict(controller: str, lines: list[str], name: str, token: str) -> str | None:
    """wtftc's own verdict on a .IN whose one value ``name`` is ``token``: None if it
    accepts it, else why not (the layout's groups by wtftc.config's own checks; the FDI's
    by discon_checks.checks, the library's table)."""
    try:  # C's strtod also reads hexadecimal floats
        value = float.fromhex(token) if token.lower().startswith(("0x", "-0x")) \
            else float(token)
    except ValueError:
        return "not a number"
    if token.strip() != token or not token:
        return "not a number"
    if not math.isfinite(value):
        return "not finite"
    values = {n: float(v) for n, (_, v) in _values(lines).items()}
    values[name] = value
    if name == discon.DEMAND_RATE_LIMIT:  # the library's own setting: a switch
        return None if value in (0.0, 1.0) else "demand_rate_limit"
    groups = discon._groups(controller)
    group = next(g for g in groups.values() if name in lay.names(g))
    vec = np.array([values[n] for n in lay.names(group)])
    try:
        if group == "turbine_params":
            config.check_turbine(vec)
        elif group == groups["controller"]:
            vals = config.check_ranges(group, vec, "controller_params")
            for low in (n for n in vals if n.endswith("pitch_min")):
                if vals[low] >= vals[low.replace("pitch_min", "pitch_max")]:
                    return "pitch order"
            if "control_sign" in vals and vals["control_sign"] not in (-1.0, 1.0):
                return "control_sign"
            if any(vals[f] not in (0.0, 1.0) for f in config.CONTROLLER_FLAGS if f in vals):
                return "a switch"
        elif group == "sensor_params":
            config.check_ranges(group, vec, "sensors")
        elif group == "fdi_params":
            rc = discon.run_config(controller)
            row = next(r for r in discon_checks.checks(rc, groups)["ranges"] if r[0] == name)
            _, lo, hi, lo_open, hi_open, *_ = row
            if value < lo or value > hi or (lo_open and value == lo) or (
                    hi_open and value == hi):
                return "FDI range"
            if name.endswith("pitch_min") and value >= values[
                    name.replace("pitch_min", "pitch_max")]:
                return "pitch order"
            if name.endswith("pitch_max") and values[
                    name.replace("pitch_max", "pitch_min")] >= value:
                return "pitch order"
    except ConfigError as exc:
        return str(exc)
    if any(values[n] >= values["yd_0"] for n in values if n.endswith("_ps_speed")):
        return "peak shaving's start speed"
    env = lay.layout()["envelope"]
    if not (env["stall_under_rated"] * values["omega_g_rated"] < values["yd_0"]
            < env["overspeed_over_rated"] * values["omega_g_rated"]):
        return "envelope"
    return None


def test_mutated_input_files_never_give_a_non_finite_demand_nor_a_crash(libs, tmp_path):
    total, refused, accepted, checked = 0, 0, 0, 0
    verdicts = {"refused": 0, "accepted": 0}
    for seed, (controller, n) in enumerate(CASES.items()):
        lib_dir = libs[controller]
        lines = (lib_dir / f"wtftc_{controller}.IN").read_text().splitlines()
        folder = tmp_path / controller
        folder.mkdir()
        cases = _cases(controller, lib_dir, folder, n, seed)
        results = []
        for b in range(0, n, BATCH):
            results += _run_batch(lib_dir / f"libwtftc_{controller}.so",
                                  cases[b:b + BATCH], folder, f"batch{b}")
        for k, (case, calls) in enumerate(zip(cases, results, strict=True)):
            where = f"{controller} case {k} ({case['infile']}, #49 = {case['capacity']})"
            cap = int(case["capacity"]) if case["capacity"] >= 1 else 0
            for call in calls:
                assert call["fail"] in (0, -1), where
                if call["fail"] == 0:
                    assert all(math.isfinite(d) for d in call["demands"]), (where, call)
                # avcMSG: nothing beyond #49 bytes, a NUL within them
                assert call["within"] and call["terminated"], (where, call)
                if cap == 0:
                    assert call["untouched"], where
                elif call["fail"] and cap > 30:
                    assert call["msg"].startswith(f"wtftc {controller}: "), (where, call)
                    assert call["msg_len"] <= cap - 1, where
            first, later = calls[0], calls[1:4]
            if first["fail"]:  # refused at the first call: nothing runs after it
                refused += 1
                assert all(c["fail"] == -1 for c in later), where
                if cap > 1000 and " at t = " in first["msg"]:
                    # read, but its first step refused (a value no range bounds, such as
                    # y_d^(3) = 1.8e308, gave a demand that is not finite): so is every
                    # later step, each saying why
                    assert all(" at t = " in c["msg"] for c in later), where
                elif cap > 1000:
                    assert all("before a first call" in c["msg"] for c in later), where
            else:
                accepted += 1
            if case["set_one"] is not None:  # the verdict is wtftc's own
                name, token = case["set_one"]
                why = _verdict(controller, lines, name, token)
                msg = first["msg"]
                if cap > 1000:
                    verdicts["accepted" if why is None else "refused"] += 1
                if cap > 1000 and why is not None:
                    checked += 1
                    assert first["fail"] == -1 and re.search(rf"\b{name}\b", msg), (
                        where, why, msg)
                elif cap > 1000:
                    checked += 1
                    assert f"{name} = " not in msg or "not allowed" not in msg, (where, msg)
            total += 1
    # the corpus reaches both ends: refusals and accepted files that ran
    assert total == sum(CASES.values()) and refused > 100 and accepted > 50, (
        total, refused, accepted)
    print(f"{total} cases: {refused} refused at the first call, {accepted} accepted; "
          f"{checked} verdicts compared with wtftc's ({verdicts})")
    assert checked > 100 and verdicts["refused"] > 30 and verdicts["accepted"] > 30, (
        checked, verdicts)
