"""The measured matrix of docs/openfast.md: the NREL 5-MW compare matrix in OpenFAST
and the same on wtftc's tower plant, the NTM cells of the two engines on the same TurbSim
field. Run from the repository (each engine's run takes its own --out):

    python examples/openfast_matrix.py openfast out/matrix_openfast
    python examples/openfast_matrix.py wtftc out/matrix_wtftc

ROSCO, the PI, the physical AFTC and the paper's design, both with wtftc's FDI, x every
actuator fault (from 20 s) x steady 16 and 20 m/s, NTM class B 12 and 16 m/s; 60 s, seed
0, the realistic profile. About 45 minutes on 2 cores for OpenFAST, a minute for wtftc.
The command line gives the same matrix, but for the shared field of the NTM cells on
wtftc's plant: wtftc compare --engine openfast --controllers rosco pi physical-plain
paper-fdi --winds steady_16 steady_20 ntm_B_12 ntm_B_16
"""

import sys
from pathlib import Path

from wtftc.campaign import compare

if __name__ == "__main__":
    engine, out = sys.argv[1], Path(sys.argv[2])
    for name, table in compare.WINDS.items():
        if table["kind"] == "ntm":  # the TurbSim field OpenFAST runs on, on both engines
            compare.WINDS[name] = {**table, "field": "turbsim"}
    compare.run_compare(out, controllers=["rosco", "pi", "physical-plain", "paper-fdi"],
                        winds=["steady_16", "steady_20", "ntm_B_12", "ntm_B_16"],
                        t_final=60.0, seed=0, engine=engine, plant="tower")
