"""SymPy's LagrangesMethod on the planar n-link pendulum (the text our engine parses, written
as a SymPy user writes it): the mass matrix W and forcing F. Cold: the first derivation in this
process (after the imports); warm: the same derivation repeated in the process (SymPy's cache
filled), median and minimum.

    python sympy_lagranges.py [N ...]     (default 2 5; 10 takes about 30 s per derivation)
"""

import sys
import time

import sympy as sp
from sympy.physics.mechanics import LagrangesMethod, dynamicsymbols

from common import emit, n_link_positions, note, repeat


def derive(n):
    th = dynamicsymbols(f"th1:{n + 1}")
    m = sp.symbols(f"m1:{n + 1}", positive=True)
    l = sp.symbols(f"l1:{n + 1}", positive=True)
    g = sp.symbols("g", positive=True)
    xs, ys = n_link_positions(n, sp.sin, sp.cos, th, l)
    t = dynamicsymbols._t
    L = sum(m[k] * (sp.diff(xs[k], t) ** 2 + sp.diff(ys[k], t) ** 2) / 2 - m[k] * g * ys[k] for k in range(n))
    lm = LagrangesMethod(L, th)
    lm.form_lagranges_equations()
    return lm.mass_matrix, lm.forcing


def main():
    ns = [int(a) for a in sys.argv[1:]] or [2, 5]
    for n in ns:
        t = time.perf_counter()
        derive(n)
        cold = time.perf_counter() - t
        emit("SymPy LagrangesMethod", "n_link_derive_W_F", "cold-first-call", n, [cold])
        if cold < 5.0:
            times, _ = repeat(lambda: derive(n), budget=2.0)
            emit("SymPy LagrangesMethod", "n_link_derive_W_F", "warm", n, times)
        else:
            note(f"sympy n={n}: first call {cold:.1f} s; warm repeats skipped")


if __name__ == "__main__":
    main()
