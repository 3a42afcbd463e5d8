"""The rotor performance table reader and the raw (bilinear) aerodynamic reference."""

from __future__ import annotations

import importlib.resources
import json
import math

import numpy as np
import pytest

from wtftc.errors import ConfigError
from wtftc.model.cp_table import (
    NREL5MW_SOURCE,
    CpTable,
    aero_torque_raw,
    nrel5mw_cp_table,
    read_cp_table,
    steady_pitch_raw,
    write_cp_table,
)

NREL_SHA256 = "a8d9c2d88bd1d9073287256b042d7752d2202a01e611c08e283b9109504caf5b"
OMEGA_RATED = 1.26711  # Rated rotor speed (rad/s), NREL 5-MW (DESIGN.md)
# Rated generator torque 43,093.55 N m (HSS) times gearbox ratio 97 -> LSS torque. The
# generator efficiency (94.4 %) is excluded: this is the shaft torque the rotor must
# deliver to hold rated generator torque, not the electrical power divided by omega.
TORQUE_RATED_LSS = 43093.55 * 97.0


def packaged_text() -> str:
    return (importlib.resources.files("wtftc") / "data" / "Cp_Ct_Cq.NREL5MW.txt").read_text()


# --------------------------------------------------------------------------- packaged table


def test_nrel5mw_grid():
    t = nrel5mw_cp_table()
    assert t.source == NREL5MW_SOURCE
    assert t.sha256 == NREL_SHA256
    # The file says 36 pitch angles -5..30 deg by 1 deg and 26 TSRs 2..14.5 by 0.5.
    np.testing.assert_allclose(np.rad2deg(t.pitch_rad), np.arange(-5.0, 31.0), atol=1e-12)
    np.testing.assert_array_equal(t.tsr, np.arange(2.0, 14.51, 0.5))
    assert t.cp.shape == t.ct.shape == t.cq.shape == (26, 36)
    np.testing.assert_array_equal(t.wind_speed, [11.4])
    # Negative coefficients are in the file (driven rotor at high TSR and pitch): kept.
    assert t.cp.min() == pytest.approx(-11.852766, abs=0)
    assert not t.cp.flags.writeable


def test_nrel5mw_cp_max():
    t = nrel5mw_cp_table()
    cp_max, tsr_at, pitch_at = t.cp_max()
    # DESIGN.md quotes Cp_max 0.4659 (4 decimals); the file has 0.465861 (6 decimals).
    # Tolerance 5e-5 = half a unit in DESIGN's last digit: the quoted value is its rounding.
    assert cp_max == pytest.approx(0.4659, abs=5e-5)
    assert cp_max == 0.465861
    # Location on the grid, so exact: TSR 7.5, pitch 0 deg.
    assert tsr_at == 7.5
    assert pitch_at == 0.0


def test_describe_is_json_and_complete():
    d = nrel5mw_cp_table().describe()
    back = json.loads(json.dumps(d))
    assert back["sha256"] == NREL_SHA256
    assert (back["n_pitch"], back["n_tsr"]) == (36, 26)
    assert (back["pitch_min_deg"], back["pitch_max_deg"]) == (-5.0, 30.0)
    assert (back["tsr_min"], back["tsr_max"]) == (2.0, 14.5)
    assert (back["cp_max"], back["cp_max_tsr"], back["cp_max_pitch_deg"]) == (0.465861, 7.5, 0.0)


def test_read_path_equals_packaged(tmp_path):
    p = tmp_path / "nrel.txt"
    p.write_text(packaged_text())
    a, b = read_cp_table(p), nrel5mw_cp_table()
    assert a.source == str(p) and a.sha256 == b.sha256
    for name in ("pitch_rad", "tsr", "cp", "ct", "cq"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))


# --------------------------------------------------------------------------- round trip


def synthetic_table() -> CpTable:
    rng = np.random.default_rng(7)
    pitch = np.deg2rad([-2.0, 0.0, 3.5])
    tsr = np.array([3.0, 5.0, 7.25, 9.0])
    cp = rng.uniform(-0.3, 0.5, (4, 3))
    return CpTable(pitch_rad=pitch, tsr=tsr, cp=cp, ct=rng.uniform(0, 1.2, (4, 3)),
                   cq=cp / tsr[:, None], source="synthetic", wind_speed=[10.0])


def test_write_read_round_trip(tmp_path):
    t = synthetic_table()
    p = write_cp_table(t, tmp_path / "Cp_Ct_Cq.synthetic.txt")
    r = read_cp_table(p)
    # 17 significant digits: values come back bit for bit; pitch passes deg<->rad once.
    np.testing.assert_allclose(r.pitch_rad, t.pitch_rad, rtol=4e-16, atol=0)
    for name in ("tsr", "cp", "ct", "cq", "wind_speed"):
        np.testing.assert_array_equal(getattr(r, name), getattr(t, name))
    # And the written file is stable: writing what was read gives the same bytes.
    p2 = write_cp_table(r, tmp_path / "again.txt")
    assert p2.read_bytes() == p.read_bytes()


def test_optional_sections_and_old_spelling(tmp_path):
    text = packaged_text().replace("# Torque coefficient", "# Torque coefficent")
    p = tmp_path / "old.txt"
    p.write_text(text)
    assert read_cp_table(p).cq is not None
    t = synthetic_table()
    bare = CpTable(t.pitch_rad, t.tsr, t.cp, None, None, "bare")
    r = read_cp_table(write_cp_table(bare, tmp_path / "bare.txt"))
    assert r.ct is None and r.cq is None and r.wind_speed is None


# --------------------------------------------------------------------------- malformed files


def write(tmp_path, text: str):
    p = tmp_path / "bad.txt"
    p.write_text(text)
    return p


def lines_of_packaged() -> list[str]:
    return packaged_text().splitlines()


def expect_error(path, *fragments: str) -> ConfigError:
    with pytest.raises(ConfigError) as info:
        read_cp_table(path)
    err = info.value
    assert err.field == "cp_table"
    assert err.where == str(path)
    for frag in fragments:
        assert frag in str(err), (frag, str(err))
    return err


def test_missing_file(tmp_path):
    expect_error(tmp_path / "nope.txt", "nope.txt", "an existing file")


@pytest.mark.parametrize("header, name", [
    ("# Power coefficient", "Power coefficient"),
    ("# TSR vector, 26 entries - y axis (matrix rows) (-)", "TSR vector"),
    ("# Pitch angle vector, 36 entries - x axis (matrix columns) (deg)", "Pitch angle vector"),
])
def test_missing_section(tmp_path, header, name):
    text = packaged_text()
    assert header in text
    # Drop the section: its header and the numbers under it up to the next header.
    lines = text.splitlines()
    k = lines.index(header)
    end = next(i for i in range(k + 1, len(lines)) if lines[i].startswith("#"))
    text = "\n".join(lines[:k] + lines[end:])
    expect_error(write(tmp_path, text), f"no '{name}' section")


def test_wrong_shape_cp_rows_refused(tmp_path):
    lines = lines_of_packaged()
    k = lines.index("# Power coefficient")
    del lines[k + 5]  # one TSR row fewer
    expect_error(write(tmp_path, "\n".join(lines)), "'Power coefficient' matrix",
                 "has 25 rows", "26 rows (one per TSR) x 36 columns")


def test_wrong_shape_cp_columns_refused(tmp_path):
    lines = lines_of_packaged()
    k = lines.index("# Power coefficient")
    row = k + 2
    lines[row] = " ".join(lines[row].split()[:-1])  # one pitch value fewer on this row
    expect_error(write(tmp_path, "\n".join(lines)), f"line {row + 1} has 35 values",
                 "36 values per row")


def test_transposed_cp_refused(tmp_path):
    t = synthetic_table()
    p = write_cp_table(t, tmp_path / "t.txt")
    text = p.read_text()
    cp_block = "".join("   ".join(f"{v:.17g}" for v in r) + "\n" for r in t.cp)
    cp_t_block = "".join("   ".join(f"{v:.17g}" for v in r) + "\n" for r in t.cp.T)
    assert cp_block in text
    expect_error(write(tmp_path, text.replace(cp_block, cp_t_block)),
                 "has 4 values", "expected 4 rows (one per TSR) x 3 columns (one per pitch)")


def test_thrust_shape_checked_too(tmp_path):
    lines = lines_of_packaged()
    k = next(i for i, s in enumerate(lines) if "Thrust coefficient" in s)
    lines.insert(k + 3, lines[k + 2])  # one TSR row too many
    expect_error(write(tmp_path, "\n".join(lines)), "'Thrust coefficient' matrix", "27 rows")


def test_non_numeric_entry_names_line(tmp_path):
    lines = lines_of_packaged()
    k = lines.index("# Power coefficient")
    row = k + 10
    lines[row] = lines[row].replace("0.", "O.", 1)  # letter O for zero, a typical typo
    expect_error(write(tmp_path, "\n".join(lines)), f"at line {row + 1}", "non-numeric")


def test_non_finite_entry_refused(tmp_path):
    lines = lines_of_packaged()
    k = lines.index("# Power coefficient")
    parts = lines[k + 2].split()
    parts[3] = "nan"
    lines[k + 2] = "   ".join(parts)
    expect_error(write(tmp_path, "\n".join(lines)), f"at line {k + 3}", "non-finite")


def test_non_monotonic_pitch(tmp_path):
    text = packaged_text().replace("-2.0   -1.0   0.0", "-2.0   0.0   -1.0", 1)
    expect_error(write(tmp_path, text), "'Pitch angle vector' not strictly increasing",
                 "0 then -1 deg")


def test_non_monotonic_tsr(tmp_path):
    text = packaged_text().replace("7.0    7.5    8.0", "7.0    7.0    8.0", 1)
    expect_error(write(tmp_path, text), "'TSR vector' not strictly increasing", "7 then 7")


def test_entry_count_in_header_checked(tmp_path):
    text = packaged_text().replace("Pitch angle vector, 36 entries", "Pitch angle vector, 37 "
                                   "entries", 1)
    expect_error(write(tmp_path, text), "has 36 entries but its header says 37")


def test_numbers_before_any_section(tmp_path):
    expect_error(write(tmp_path, "1 2 3\n" + packaged_text()), "before any section",
                 "line 1")


def test_unknown_header_does_not_swallow_numbers(tmp_path):
    # A misspelt header must not let the Ct rows run on into the Cp matrix.
    text = packaged_text().replace("#  Thrust coefficient", "#  Thrust coeffs", 1)
    expect_error(write(tmp_path, text), "under the header '#  Thrust coeffs' (line 41)",
                 "names no known section")


def test_direct_construction_checks_shape():
    t = synthetic_table()
    with pytest.raises(ValueError, match=r"shape \(3, 4\); expected \(4, 3\)"):
        CpTable(t.pitch_rad, t.tsr, t.cp.T, None, None, "x")


# --------------------------------------------------------------------------- raw reference


def test_aero_torque_raw_at_grid_node():
    t = nrel5mw_cp_table()
    # TSR 7.5 at v = 10 m/s needs omega = 7.5 * 10 / 63; pitch 0 is a grid node.
    omega, v = 7.5 * 10.0 / 63.0, 10.0
    expected = 0.5 * 1.225 * math.pi * 63.0**2 * v**3 * 0.465861 / omega
    assert aero_torque_raw(t, omega, v, 0.0) == pytest.approx(expected, rel=1e-12)


def test_aero_torque_raw_is_bilinear_between_nodes():
    t = nrel5mw_cp_table()
    v = 10.0
    tsr, pitch = 7.25, np.deg2rad(0.5)  # the centre of the cell TSR 7..7.5, pitch 0..1 deg
    omega = tsr * v / 63.0
    cell = t.cp[10:12, 5:7]
    cp_centre = cell.mean()
    expected = 0.5 * 1.225 * math.pi * 63.0**2 * v**3 * cp_centre / omega
    assert aero_torque_raw(t, omega, v, pitch) == pytest.approx(expected, rel=1e-12)


def test_aero_torque_raw_refuses_outside_table():
    t = nrel5mw_cp_table()
    with pytest.raises(ValueError, match="tip-speed ratio"):
        aero_torque_raw(t, OMEGA_RATED, 50.0, 0.0)  # TSR 1.6 < 2
    with pytest.raises(ValueError, match="pitch"):
        aero_torque_raw(t, OMEGA_RATED, 12.0, np.deg2rad(31.0))


def test_steady_pitch_raw_above_rated():
    t = nrel5mw_cp_table()
    pitches = []
    for v in (12.0, 16.0, 20.0):
        beta = steady_pitch_raw(t, OMEGA_RATED, TORQUE_RATED_LSS, v)
        torque = aero_torque_raw(t, OMEGA_RATED, v, beta)
        assert torque == pytest.approx(TORQUE_RATED_LSS, rel=1e-6)
        assert t.pitch_rad[0] <= beta <= t.pitch_rad[-1]
        pitches.append(beta)
    assert pitches[0] < pitches[1] < pitches[2]
    # Above the pitch of Cp max (0 deg) and well inside the table: about 3.6, 12.0, 17.3 deg.
    np.testing.assert_allclose(np.rad2deg(pitches), [3.60, 11.96, 17.35], atol=0.01)
    # Pitching to feather lowers the torque there: dT/dbeta < 0 (DESIGN.md finding 2).
    assert aero_torque_raw(t, OMEGA_RATED, 12.0, pitches[0] + 1e-3) < TORQUE_RATED_LSS


def test_steady_pitch_raw_no_root_is_valueerror():
    t = nrel5mw_cp_table()
    # At rated wind 11.4 m/s the rotor at rated speed cannot reach rated shaft torque.
    with pytest.raises(ValueError, match="exceeds the largest aerodynamic torque") as info:
        steady_pitch_raw(t, OMEGA_RATED, TORQUE_RATED_LSS, 11.4)
    assert not isinstance(info.value, ConfigError)
    # A torque so small (negative: motoring) that 30 deg of pitch cannot shed enough.
    with pytest.raises(ValueError, match="beyond the table's pitch range"):
        steady_pitch_raw(t, OMEGA_RATED, -1e9, 12.0)


def test_a_table_that_never_makes_power_is_refused(tmp_path):
    """A Cp table with no positive Cp has no rated wind ((2P/(ρAπ Cp_max))^(1/3) of a
    negative number) and no operating point: refused when read, not a TypeError later."""
    t = synthetic_table()
    p = write_cp_table(CpTable(pitch_rad=t.pitch_rad, tsr=t.tsr, cp=-np.abs(t.cp) - 0.01,
                               ct=t.ct, cq=t.cq, source="test"), tmp_path / "neg.txt")
    expect_error(p, "largest Cp", "positive power coefficient")
