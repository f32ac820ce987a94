"""Measure the small-stick law and write ``notebooks/data/small_stick_law.npz``.

The largest Lyapunov exponent of a short stick, per unit time and per
collision, in the circle (R = 2) and the ellipse (a = 2, b = 1.4), at fixed
I = 1 and with the paper's I = M ell^2, for ell = 0.1 ... 1e-6: 512 Liouville
starts on the shell E = 1/2 per point, a common time window, 8 sub-ensembles
for the error bars (``jaxbill.studies.small_stick.measure_small_stick_law``).
Also stores the reduced map's predicted prefactors.

Run (about 5-10 minutes on one core of a shared machine)::

    taskset -c 1 python notebooks/data/make_small_stick_data.py
"""

from __future__ import annotations

import json
import pathlib
import time

import numpy as np

from jaxbill.studies import small_stick as ss

OUT = pathlib.Path(__file__).resolve().parent / "small_stick_law.npz"


def main():
    started = time.perf_counter()
    data = ss.measure_small_stick_law(log=lambda line: print(line, flush=True))
    coefficients = ss.predicted_coefficients()
    for k, v in coefficients.items():
        data[f"prediction/{k}"] = np.array(v)
    seconds = time.perf_counter() - started
    meta = json.loads(str(data["meta"]))
    meta["total_seconds"] = seconds
    data["meta"] = np.array(json.dumps(meta))
    np.savez_compressed(OUT, **data)
    print(f"wrote {OUT} in {seconds:.0f} s")


if __name__ == "__main__":
    main()
