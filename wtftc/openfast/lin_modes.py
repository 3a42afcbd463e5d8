"""Modes of OpenFAST's linearization (issue 33 item 2; ours): its ``.lin`` files read,
the rotating blade states taken to the fixed frame (MBC3), averaged over the azimuths,
the generator-azimuth state removed, and the modes named by participation. numpy only;
openfast-io's ``FASTLinearizationFile`` reads the files.

**MBC3** (Bir 2008, "Multi-blade coordinate transformation and its application to wind
turbine analysis", NREL/CP-500-42553; ROSCO's ``rosco.toolbox.linear.mbc3.fx_mbc3`` gives
the same). For each blade triplet of a rotating state, q_b = q_0 + q_c cos ψ_b + q_s sin ψ_b
with ψ_b = ψ + 2π(b − 1)/3 (ψ: blade 1's azimuth, Ω: the rotor speed of the file):

    q = T1 q_n,   q̇ = T1 q̇_n + Ω T2 q_n,   q̈ = T1 q̈_n + 2Ω T2 q̇_n + (Ω² T3 + Ω̇ T2) q_n
    x = L x_n,    A_n = L⁻¹ (A L − L̇)

with t1 = [1 cos ψ_b sin ψ_b], t2 = [0 −sin ψ_b cos ψ_b], t3 = [0 −cos ψ_b −sin ψ_b] per
blade row. Averaged over azimuths equally spaced in one revolution (what ``CalcSteady``
gives), A_n is the time-invariant model whose eigenvalues are the modes.

**Participation** (Pérez-Arriaga, Verghese, Schweppe 1982): p_ki = |l_ki r_ki| of the left
and right eigenvectors (l_k r_k = 1), independent of the states' units; a degree of
freedom's share is the sum over its displacement and its rate, normalised per mode.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

#: the generator azimuth: a pure integrator of the rotor speed, removed before the eigen-
#: analysis (its averaged periodic column otherwise gives a spurious real pair)
AZIMUTH = "Variable speed generator"
DRIVETRAIN = "Drivetrain rotational-flexibility"
TOWER_FA = "1st tower fore-aft bending mode"
TOWER_SS = "1st tower side-to-side bending mode"
#: the goal of issue 33: modal frequencies within 3 %
FREQUENCY_GOAL = 0.03


@dataclass
class Linearization:
    """The .lin files of one operating point: A at each azimuth (n × n × N), each
    state's description, rotating frame and derivative order, the azimuths [rad] and
    rotor speeds [rad/s]."""

    A: np.ndarray
    desc: list[str]
    rotating: np.ndarray
    order: np.ndarray
    azimuth: np.ndarray
    rotor_speed: np.ndarray


def read(files: list[Path]) -> Linearization:
    """The .lin files of one operating point (openfast-io's reader, no pandas)."""
    from openfast_io.FAST_linearization_reader import FASTLinearizationFile

    lins = [FASTLinearizationFile(str(f)) for f in files]
    info = lins[0]["x_info"]
    return Linearization(
        A=np.stack([np.asarray(f["A"], dtype=float) for f in lins], axis=2),
        desc=[str(d) for d in info["Description"]],
        rotating=np.array([str(s).strip() == "T" for s in info["RotatingFrame"]]),
        order=np.array([int(o) for o in info["DerivativeOrder"]]),
        azimuth=np.array([float(f["Azimuth"]) for f in lins]),
        rotor_speed=np.array([float(f["RotSpeed"]) for f in lins]))


def dof_name(desc: str) -> str:
    """A state's degree of freedom, short: 'ED 1st tower fore-aft bending mode DOF
    (internal DOF index = DOF_TFA1), m' and its 'First time derivative of ...' both give
    '1st tower fore-aft bending mode'."""
    s = desc.split(" (internal")[0].split(", ")[0]
    s = re.sub(r"^[A-Za-z]+ ", "", s, count=1)  # the module: ED, AD, ...
    s = s.replace("First time derivative of ", "")
    return re.sub(r" DOF\b", "", s).strip()


def _triplets(lin: Linearization, rows) -> list[tuple[int, int, int]]:
    """The rotating states among ``rows`` grouped by blade: (blade 1, 2, 3) per kind."""
    groups: dict[str, dict[int, int]] = {}
    for i in rows:
        m = re.search(r"blade (\d)", lin.desc[i], re.IGNORECASE)
        if not lin.rotating[i] or m is None:
            continue
        key = re.sub(r"blade \d", "blade #", lin.desc[i], flags=re.IGNORECASE)
        key = re.sub(r"\((\w+)\(\d,", r"(\1(#,", re.sub(r"DOF_B([FE])\(\d", r"DOF_B\1(#", key))
        groups.setdefault(key, {})[int(m.group(1))] = i
    return [tuple(g[b] for b in (1, 2, 3)) for g in groups.values() if len(g) == 3]


def _blocks(psi: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """t1, t2, t3 of MBC3 at blade 1's azimuth ``psi`` [rad] (3 × 3 each)."""
    az = psi + 2 * np.pi / 3 * np.arange(3)
    c, s, one, zero = np.cos(az), np.sin(az), np.ones(3), np.zeros(3)
    return (np.column_stack([one, c, s]), np.column_stack([zero, -s, c]),
            np.column_stack([zero, -c, -s]))


def mbc3(lin: Linearization) -> tuple[np.ndarray, list[tuple[int, int, int]]]:
    """A in the fixed frame at each azimuth (n × n × N) and the blade triplets of the
    displacements (whose slots then read collective, cosine, sine). The states are
    OpenFAST's order: second-order displacements, their rates, then first-order states."""
    n, _, N = lin.A.shape
    nd = int(np.sum(lin.order == 2)) // 2
    trip2 = _triplets(lin, range(nd))
    trip1 = [tuple(k - 2 * nd for k in t) for t in _triplets(lin, range(2 * nd, n))]
    n1 = n - 2 * nd
    out = np.empty_like(lin.A)
    for k in range(N):
        t1, t2, t3 = _blocks(lin.azimuth[k])
        W = lin.rotor_speed[k]
        T1, T2, T3 = np.eye(nd), np.zeros((nd, nd)), np.zeros((nd, nd))
        for tr in trip2:
            ix = np.ix_(tr, tr)
            T1[ix], T2[ix], T3[ix] = t1, t2, t3
        Q1, Q2 = np.eye(n1), np.zeros((n1, n1))
        for tr in trip1:
            ix = np.ix_(tr, tr)
            Q1[ix], Q2[ix] = t1, t2
        Z, Zq = np.zeros((nd, nd)), np.zeros((nd, n1))
        L = np.block([[T1, Z, Zq], [W * T2, T1, Zq], [Zq.T, Zq.T, Q1]])
        Ld = np.block([[W * T2, Z, Zq], [W ** 2 * T3, W * T2, Zq], [Zq.T, Zq.T, W * Q2]])
        out[:, :, k] = np.linalg.solve(L, lin.A[:, :, k] @ L - Ld)
    return out, trip2


def fixed_frame_names(lin: Linearization, trip2) -> list[str]:
    """Each state's degree of freedom after MBC3: a blade triplet's three slots named
    '... collective', '... cosine', '... sine' (and their rates likewise)."""
    names = [dof_name(d) for d in lin.desc]
    nd = int(np.sum(lin.order == 2)) // 2
    for tr in trip2:
        base = re.sub(r" of blade \d", "", names[tr[0]], flags=re.IGNORECASE)
        for i, kind in zip(tr, ("collective", "cosine", "sine"), strict=True):
            names[i] = names[i + nd] = f"{base} {kind}"
    return names


def averaged(lin: Linearization) -> tuple[np.ndarray, list[str]]:
    """The time-invariant model: A after MBC3, averaged over the azimuths, with the
    generator-azimuth displacement removed (its rate, the rotor speed, kept); each
    remaining state's degree of freedom."""
    A_nr, trip2 = mbc3(lin)
    names = fixed_frame_names(lin, trip2)
    keep = [i for i, d in enumerate(lin.desc)
            if not (AZIMUTH in d and "First time derivative" not in d)]
    return A_nr.mean(axis=2)[np.ix_(keep, keep)], [names[i] for i in keep]


def modes(A: np.ndarray, names: list[str]) -> list[dict]:
    """The oscillatory modes of ẋ = A x (one of each complex pair), slowest first: natural
    frequency [Hz], damping ratio [-], eigenvalue, each name's participation (summed over
    the states of that name, normalised to 1) and the right eigenvector."""
    lam, R = np.linalg.eig(A)
    Lft = np.linalg.inv(R)  # rows: left eigenvectors with l_k r_k = 1
    out = []
    for k in np.argsort(np.abs(lam)):
        if lam[k].imag <= 1e-9 * max(1.0, abs(lam[k])):
            continue
        p = np.abs(Lft[k, :] * R[:, k])
        share: dict[str, float] = {}
        for name, v in zip(names, p / p.sum(), strict=True):
            share[name] = share.get(name, 0.0) + float(v)
        wn = float(abs(lam[k]))
        out.append({"f_hz": wn / (2 * np.pi), "zeta": float(-lam[k].real / wn),
                    "eigenvalue": complex(lam[k]), "share": share, "vector": R[:, k]})
    return out


def dominant(mode: dict, n: int = 3) -> list[tuple[str, float]]:
    """The ``n`` names of largest participation in ``mode``, with their shares."""
    return sorted(mode["share"].items(), key=lambda kv: -kv[1])[:n]


def amplitude(mode: dict, names: list[str], dof: str) -> complex:
    """The displacement of ``dof`` in ``mode``'s right eigenvector: its displacement
    state's entry, or its rate's divided by the eigenvalue (a state kept only as a rate,
    the generator azimuth). 0 when the model lacks it."""
    rows = [i for i, n in enumerate(names) if n == dof]
    if not rows:
        return 0j
    v = mode["vector"]
    return complex(v[rows[0]]) if len(rows) > 1 else complex(v[rows[0]] / mode["eigenvalue"])


def drivetrain(ms: list[dict], twist, ratio) -> dict | None:
    """The drivetrain mode, the generator swinging against the rotor: among the modes in
    which the shaft twists (a ``twist(m)`` share at least a quarter of the largest) against
    the generator (Re ``ratio(m)`` < 0, ratio = twist / generator angle), the one where
    the generator moves most per twist (least |ratio|). With flexible blades the twist
    also leads a mode of the hub against the blades' collective edgewise bending, where
    the generator hardly moves (|ratio| 3.6 on the NREL 5-MW against 0.65)."""
    top = max((twist(m) for m in ms), default=0.0)
    cands = [m for m in ms if top > 0 and twist(m) >= 0.25 * top and ratio(m).real < 0]
    return min(cands, key=lambda m: abs(ratio(m)), default=None)


def find(ms: list[dict], names: list[str]) -> dict[str, dict | None]:
    """OpenFAST's modes to compare: the drivetrain (:func:`drivetrain`), the first tower
    fore-aft and side-to-side modes (the largest share of their degree of freedom); None
    where the model lacks one."""
    def tower(dof):
        return max((m for m in ms if m["share"].get(dof, 0.0) > 0),
                   key=lambda m: m["share"][dof], default=None)

    def ratio(m):
        return amplitude(m, names, DRIVETRAIN) / (amplitude(m, names, AZIMUTH) or 1)

    return {"drivetrain": drivetrain(ms, lambda m: m["share"].get(DRIVETRAIN, 0.0), ratio),
            "tower_fa": tower(TOWER_FA), "tower_ss": tower(TOWER_SS)}
