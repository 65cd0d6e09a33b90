"""Write ``finger_bench.csv``: the worked example's bench measurements, made up for the example.

The rows are NOT measured on hardware. They are solved on an independent continuum model, the
planar elastica of ``tests/reference/rod.py`` (it shares no code with somo-sweep's chain), for a
70-mm finger with the values below, with 1 % seeded multiplicative noise, so the example can say
how close calibration gets to the truth. Run from the repository's root:

    python -m examples.own_gripper.make_bench_csv
"""

from __future__ import annotations

from pathlib import Path

from tests.reference.rod import Rod, bench_rows

#: The "true" finger the rows are solved on (SI; the gain in N·m/kPa).
TRUE_FINGER = {
    "length_m": 0.070,
    "tip_stiffness_n_m": 30.0,
    "mass_kg": 0.012,
    "half_thickness_m": 0.0075,
    "gain_n_m_per_kpa": 8e-4,
}
NOISE_REL = 0.01
SEED = 0
OUT = Path(__file__).with_name("finger_bench.csv")


def main() -> None:
    """Solve the 36-row bench plan on the elastica and write the CSV with its finger line."""
    rod = Rod.from_tip_stiffness(**TRUE_FINGER)
    rows = bench_rows(rod, noise_rel=NOISE_REL, seed=SEED)
    header = [
        "# Made-up bench rows for the worked example, NOT measured: solved on an independent planar",
        "# elastica (tests/reference/rod.py) of a 70-mm, 12-g finger with tip stiffness 30 N/m",
        f"# (EI {rod.ei_grasp_n_m2:.4g} N·m²) and pressure gain 8e-4 N·m/kPa, 1 % noise, seed 0.",
        "# finger: {length_mm: 70, segments: 12, mass_g: 12, width_mm: 20, thickness_mm: 15}",
    ]
    OUT.write_text("\n".join(header) + "\n" + rows.to_csv(index=False, float_format="%.6g"))
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
