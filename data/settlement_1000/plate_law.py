"""The settlement at the last cycle predicted from the plate alone: Shenton's law with
its constant, s = c + a ln N, fitted by least squares to full DEM's settlement over
cycles FIRST to C and carried to the last cycle, against full DEM there.

    python plate_law.py FOLDER [FOLDER ...]

Each FOLDER holds a study's paths.csv with a full_dem run (README).  Prints, per
folder, the relative error of the prediction for C = 100, 200, 300 and 500: what a
curve fitted to the plate makes of the same cycles the procedure computes from."""
import csv
import pathlib
import sys

import numpy as np

FIRST = 30              # the procedure's initial cycles, k_i [-]
LAST_FITTED = (100, 200, 300, 500)


def main(folders):
    print("folder: error at the last cycle of c + a ln N fitted over cycles 30-C")
    for folder in folders:
        rows = [r for r in csv.DictReader(open(folder / "paths.csv"))
                if r["run"] == "full_dem"]
        cycles = np.array([int(r["cycle"]) for r in rows])
        settlement = np.array([float(r["settlement_m"]) for r in rows])
        last = cycles.max()
        reference = settlement[cycles == last][0]
        errors = []
        for c in LAST_FITTED:
            fitted = (cycles >= FIRST) & (cycles <= c)
            basis = np.column_stack([np.ones(fitted.sum()), np.log(cycles[fitted])])
            coefficients = np.linalg.lstsq(basis, settlement[fitted], rcond=None)[0]
            predicted = coefficients[0] + coefficients[1] * np.log(last)
            errors.append(f"C = {c}: {100 * (predicted / reference - 1):+.1f} %")
        print(f"{folder.name}: full DEM {1e3 * reference:.3f} mm at cycle {last}; "
              + ", ".join(errors))


if __name__ == "__main__":
    main([pathlib.Path(a) for a in sys.argv[1:]])
