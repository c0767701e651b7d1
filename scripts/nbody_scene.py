#!/usr/bin/env python3
"""Writes an N-body scene: the scene language has no indexed sums, so the pairwise
Hamiltonian H = Σ |p_i|²/(2 m_i) − G Σ_{i<j} m_i m_j / |q_i − q_j| is generated here, one term
per pair, from a table of bodies. `python3 scripts/nbody_scene.py > examples/outer_solar_system.scene`
regenerates the example (tests/it/scene/examples.rs checks that it is current).

Initial conditions: the outer solar system of Hairer, Lubich & Wanner, Geometric Numerical
Integration (2nd ed., Springer 2006), Section I.2.4 (September 5, 1994; AU, days, masses
relative to the Sun, whose mass includes the inner planets), the data REBOUND's
outer-solar-system example starts from; Pluto left out.
"""

G = "2.95912208286e-4"
BODIES = [
    # name, mass, position (AU), velocity (AU/day)
    ("sun", "1.00000597682", (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)),
    ("jupiter", "0.000954786104043", (-3.5023653, -3.8169847, -1.5507963), (0.00565429, -0.00412490, -0.00190589)),
    ("saturn", "0.000285583733151", (9.0755314, -3.0458353, -1.6483708), (0.00168318, 0.00483525, 0.00192462)),
    ("uranus", "0.0000437273164546", (8.3101420, -16.2901086, -7.2521278), (0.00354178, 0.00137102, 0.00055029)),
    ("neptune", "0.0000517759138449", (11.4707666, -25.7294829, -10.8169456), (0.00288930, 0.00114527, 0.00039677)),
]
# Body k's coordinates are x_k, y_k, z_k and its mass m_k (k = 0 the Sun).
AXES = "xyz"


def barycentric(bodies):
    """The bodies in the frame of their centre of mass (as REBOUND's `move_to_com`): with the
    Sun at rest the whole system drifts by ~7e-6 AU/day, 30 AU over the run, and the rounding
    of positions that large grows the energy error linearly with time."""
    total = sum(float(m) for _, m, _, _ in bodies)
    com = [sum(float(m) * q[i] for _, m, q, _ in bodies) / total for i in range(3)]
    vcm = [sum(float(m) * v[i] for _, m, _, v in bodies) / total for i in range(3)]
    return [(name, m, tuple(q[i] - com[i] for i in range(3)), tuple(v[i] - vcm[i] for i in range(3)))
            for name, m, q, v in bodies]


def scene(orbits=1000):
    n = len(BODIES)
    coords = [f"{a}{k}" for k in range(n) for a in AXES]
    kinetic = " + ".join(f"(p_{a}{k}^2 + p_{b}{k}^2 + p_{c}{k}^2)/(2 m{k})"
                         for k in range(n) for (a, b, c) in [tuple(AXES)])
    pairs = " + ".join(
        f"m{i} m{j}/sqrt((x{i} - x{j})^2 + (y{i} - y{j})^2 + (z{i} - z{j})^2)"
        for i in range(n) for j in range(i + 1, n))
    params = ", ".join([f"G = {G}"] + [f"m{k} = {b[1]}" for k, b in enumerate(BODIES)])
    starts = []
    for k, (_, m, q, v) in enumerate(barycentric(BODIES)):
        for a, qa, va in zip(AXES, q, v):
            starts.append(f"{a}{k} = {qa!r}")
            # p = m v, written as a product with the mass so the numbers stay as given.
            starts.append(f"p_{a}{k} = m{k} * {va!r}" if va else f"p_{a}{k} = 0")
    jupiter_period = 4332.6  # days, for the time span only
    lines = [
        "# The outer solar system (Sun, Jupiter, Saturn, Uranus, Neptune) over 10³ Jupiter orbits,",
        "# integrated by the Taylor method near machine precision. Written by scripts/nbody_scene.py",
        "# (the language has no indexed sums; the script writes one term per pair). Initial",
        "# conditions: Hairer, Lubich & Wanner, Geometric Numerical Integration, §I.2.4 (AU, days).",
        "# Barycentric frame. The relative energy error stays near round-off and grows like √t",
        "# (Brouwer's law).",
        "coordinates " + ", ".join(coords),
        "parameters " + params + " positive",
        f"H = {kinetic} - G ({pairs})",
        "simulate " + ", ".join(starts) + f" for t in 0..{orbits * jupiter_period:.0f} with taylor tol = 1e-16 as solar",
        "plot energy from solar to outer_solar_system_energy.svg",
        "export from solar to outer_solar_system.csv",
    ]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    import sys
    print(scene(int(sys.argv[1]) if len(sys.argv) > 1 else 1000), end="")
