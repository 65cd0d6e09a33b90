"""Fig. 6 ablation: configurations from the ablation file, areas and headlines, the figures, the command."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pandas as pd
import pytest
from conftest import MODELS, ROOT
from typer.testing import CliRunner

from somo_sweep.cli.app import app
from somo_sweep.errors import DescriptionError, SomoError
from somo_sweep.paper.ablation import ABLATION_FILE, configurations, load_ablation
from somo_sweep.paper.fig6_ablation import PAPER_DSR, ConfigResult, area_table, build, effects_table
from somo_sweep.paper.fig6_compare import Side
from somo_sweep.paper.fig6_compare import build as build_compare

RULES = {"ours": "contacts", "original": "paper"}


def cells(spec: dict[float, list[str]], inferred: frozenset[tuple[float, int]] = frozenset()) -> pd.DataFrame:
    """A tidy grasp table: per DSR, labels of the cells (c = 70, 85 mm) x (width 10, 120 mm)."""
    rows = []
    for dsr, labels in spec.items():
        for i, label in enumerate(labels):
            rows.append(
                {
                    "distal_segment_ratio": dsr,
                    "centering_position_m": (0.070, 0.085)[i % 2],
                    "object_width_m": (0.010, 0.120)[i // 2],
                    "label": label,
                    "inferred": (dsr, i) in inferred,
                }
            )
    return pd.DataFrame(rows)


def config(name: str, contacts: pd.DataFrame, paper: pd.DataFrame, factor: str | None = None) -> ConfigResult:
    base = "original" if name.startswith("original") else "ours"
    return ConfigResult(name, base, factor, name, {"contacts": contacts, "paper": paper}, {})


# Each DSR has four cells: (c 70, w 10), (c 85, w 10), (c 70, w 120), (c 85, w 120).
OURS = cells(
    {
        0.0: ["pinch", "power", "no_grasp", "no_grasp"],  # no pinch of the 120-mm box
        0.2: ["pinch", "pinch", "pinch", "power"],  # every width pinched: the headline
        0.4: ["pinch", "pinch", "unstable", "power"],
    },
    inferred=frozenset({(0.2, 1), (0.2, 2)}),  # two of DSR 0.2's cells an adaptive run inferred
)


def test_area_is_the_fraction_of_a_dsrs_cells_inferred_ones_included() -> None:
    areas = area_table([config("ours", OURS, OURS)])
    mine = areas[areas["rule"] == "contacts"].set_index("distal_segment_ratio")
    assert mine["cells"].tolist() == [4, 4, 4]
    assert mine["inferred_cells"].tolist() == [0, 2, 0]
    assert mine["pinch_area"].tolist() == [0.25, 0.75, 0.5]
    assert mine["power_area"].tolist() == [0.25, 0.25, 0.25]
    assert mine["no_grasp_area"].tolist() == [0.5, 0.0, 0.0]  # the unstable cell counts in no label
    assert (mine["smallest_all_width_pinch_dsr"] == 0.2).all()


def test_no_all_width_pinch_is_nan_and_effects_compare_one_factor_at_a_time() -> None:
    never = cells({0.0: ["pinch", "pinch", "power", "power"], 0.2: ["pinch"] * 2 + ["no_grasp"] * 2})
    configs = [
        config("ours", OURS, never),
        config("original", never, OURS),
        config("ours+springs_x2", never, never, "springs_x2"),
        config("original-springs_x2", OURS, OURS, "springs_x2"),
    ]
    areas = area_table(configs)
    assert areas.loc[areas["configuration"] == "ours+springs_x2", "smallest_all_width_pinch_dsr"].isna().all()
    effects = effects_table(areas, ["springs_x2"], RULES).set_index("change")
    assert list(effects.index) == [
        "ours + springs_x2",
        "ours + rule (paper)",
        "original - springs_x2",
        "original - rule (contacts)",
    ]
    assert effects.loc["ours + springs_x2", "smallest_dsr_before"] == 0.2
    assert pd.isna(effects.loc["ours + springs_x2", "smallest_dsr_after"])
    assert effects.loc["ours + rule (paper)", "mean_pinch_area_before"] == pytest.approx(
        (0.25 + 0.75 + 0.5) / 3
    )
    assert effects.loc["ours + rule (paper)", "mean_pinch_area_after"] == pytest.approx(
        0.5
    )  # never: 0.5, 0.5
    assert effects.loc["original - springs_x2", "smallest_dsr_after"] == 0.2


def test_build_returns_table_markdown_and_figure_with_the_papers_dsr_marked() -> None:
    out = build([config("ours", OURS, OURS), config("original", OURS, OURS)], [], RULES, "tiny")
    assert list(out.tables) == ["fig6_ablation.csv"] and list(out.texts) == ["fig6_ablation.md"]
    assert list(out.figures) == ["fig6_ablation"] and out.formats == ("png",)
    md = out.texts["fig6_ablation.md"]
    assert "| ours | contacts | ours | 0.20 | 12 | 2 |" in md
    assert "## Pinch area per DSR" in md and "inferred" in md
    ax = out.figures["fig6_ablation"].axes[0]
    assert any(list(line.get_xdata()) == [PAPER_DSR, PAPER_DSR] for line in ax.get_lines())
    assert "ours (contacts rule): smallest all-width pinch DSR 0.20" in out.lines


def test_side_by_side_draws_one_row_per_configuration_and_the_papers_way_on_request() -> None:
    sides = [Side("ours", "contacts", OURS), Side("original", "paper", OURS)]
    plain = build_compare(sides)
    assert len(plain.figures["fig6_compare"].subfigs) == 2
    styled = build_compare(sides, paper_style=True)
    subfigs = styled.figures["fig6_compare"].subfigs
    assert len(subfigs) == 4
    assert "the paper's way" in subfigs[2]._suptitle.get_text()
    assert plain.lines == [
        "ours (contacts rule): smallest all-width pinch DSR 0.20",
        "original (paper rule): smallest all-width pinch DSR 0.20",
    ]
    panels = [ax for ax in subfigs[0].axes if ax.get_title()]
    assert all(ax.get_xlim() == pytest.approx((62.5, 92.5)) for ax in panels)


def test_bundled_ablation_makes_every_configuration_and_shares_coinciding_ones(tmp_path: Path) -> None:
    spec, folder = load_ablation(ABLATION_FILE)
    configs = {c.name: c for c in configurations(spec, folder, "quick", tmp_path)}
    assert list(configs) == [
        "ours",
        "original",
        "ours+springs_x2",
        "ours+point_contacts",
        "original-springs_x2",
        "original-point_contacts",
    ]
    assert configs["ours"].folder == tmp_path / "pinch_grasp_quick_ablation_ours"
    assert configs["original"].folder == tmp_path / "pinch_grasp_quick_original"
    # With two physical factors, ours + one factor is the original without the other.
    assert configs["original-point_contacts"].same_as == "ours+springs_x2"
    assert configs["original-point_contacts"].folder == configs["ours+springs_x2"].folder
    assert len({c.table.study_hash for c in configs.values()}) == 4
    assert all(len(c.table.jobs) == 192 for c in configs.values())


def test_the_bundled_configurations_simulate_each_factor_at_its_end(tmp_path: Path) -> None:
    # Springs x2 is the designer's spring_scale; point contacts the original block's spinning friction.
    spec, folder = load_ablation(ABLATION_FILE)
    expected = {
        "ours": (1.0, None),
        "original": (2.0, 0.0),
        "ours+springs_x2": (2.0, None),
        "ours+point_contacts": (1.0, 0.0),
        "original-springs_x2": (1.0, 0.0),
        "original-point_contacts": (2.0, None),
    }
    for config in configurations(spec, folder, "quick", tmp_path):
        seen = {
            (j.params.spring_scale, j.params.original.finger_spinning_friction_m) for j in config.table.jobs
        }
        assert seen == {expected[config.name]}, config.name
        assert config.study.notices == ()
    assert spec.notices == ()


def test_an_ablation_file_with_the_old_names_makes_the_same_configurations_with_a_notice(
    tmp_path: Path,
) -> None:
    text = ABLATION_FILE.read_text()
    old = tmp_path / "ablation.yaml"
    old.write_text(
        text.replace("task.original.finger_spinning_friction_m", "task.finger_spinning_friction_m")
    )
    for name in ("pinch_grasp_quick_ablation_ours.yaml", "pinch_grasp_quick_original.yaml"):
        study = (ABLATION_FILE.parent / name).read_text().replace("models/", f"{MODELS}/")
        (tmp_path / name).write_text(
            study.replace("original: {finger_spinning_friction_m: 0.0}", "finger_spinning_friction_m: 0.0")
        )
    spec, folder = load_ablation(old)
    hashes = {c.name: c.table.study_hash for c in configurations(spec, folder, "quick", tmp_path)}
    bundled, bundled_folder = load_ablation(ABLATION_FILE)
    assert hashes == {
        c.name: c.table.study_hash for c in configurations(bundled, bundled_folder, "quick", tmp_path)
    }
    (notice,) = spec.notices
    line = next(n for n, s in enumerate(text.splitlines(), 1) if "ours: {task.original.finger" in s)
    new = "task.original.finger_spinning_friction_m"
    assert notice == (
        f"{old}: old parameter names read at their new place: "
        f"factors.point_contacts.ours.task.finger_spinning_friction_m (line {line}) → {new}; "
        f"factors.point_contacts.original.task.finger_spinning_friction_m (line {line + 1}) → {new}; "
        "write the new key paths to silence this note"
    )
    original = next(c for c in configurations(spec, folder, "quick", tmp_path) if c.name == "original")
    assert any("params.finger_spinning_friction_m" in n for n in original.study.notices)


def test_a_factor_giving_a_parameter_by_both_names_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "ablation.yaml"
    path.write_text(
        "name: a\ngrids: {g: {ours: a.yaml, original: b.yaml}}\nfactors:\n  f:\n"
        "    ours: {task.restitution: 0.0, task.original.restitution: 0.0}\n"
        "    original: {task.original.restitution: 0.5}\n"
    )
    with pytest.raises(DescriptionError) as info:
        load_ablation(path)
    assert info.value.problems[0].render() == (
        "line 5: factors.f.ours.task.restitution: gives task.original.restitution by the name it had "
        "before it moved, and factors.f.ours.task.original.restitution gives it too; allowed: "
        "task.original.restitution alone"
    )


def test_an_original_study_that_is_not_ours_plus_the_factors_is_refused(tmp_path: Path) -> None:
    for name in ("pinch_grasp_quick_ablation_ours.yaml", "pinch_grasp_quick_original.yaml"):
        text = (ABLATION_FILE.parent / name).read_text().replace("models/", f"{MODELS}/")
        (tmp_path / name).write_text(text.replace("spring_scale: 2.0", "spring_scale: 3.0"))
    shutil.copy(ABLATION_FILE, tmp_path / "ablation.yaml")
    spec, folder = load_ablation(tmp_path / "ablation.yaml")
    with pytest.raises(SomoError, match=r"pinch_grasp_quick_original\.yaml: its trials differ"):
        configurations(spec, folder, "quick", tmp_path)


def test_a_factor_must_set_the_same_keys_at_both_ends(tmp_path: Path) -> None:
    path = tmp_path / "ablation.yaml"
    path.write_text(
        "name: a\ngrids: {g: {ours: a.yaml, original: b.yaml}}\n"
        "factors:\n  f: {ours: {task.spring_scale: 1.0}, original: {task.original.restitution: 0.5}}\n"
    )
    with pytest.raises(DescriptionError, match=r"factors\.f.*the same key paths"):
        load_ablation(path)


def tiny_ablation(folder: Path) -> Path:
    """A one-factor ablation on 2 DSR x 2 widths x 2 centering positions, 0.2-s trials."""
    grid = (
        "task: pinch_grasp\n"
        f"model: {MODELS / 'pinch_gripper.yaml'}\n"
        "params: {approach_s: 0.05, ramp_s: 0.05, lift_s: 0.05, hold_s: 0.05%s}\n"
        "sweep:\n"
        "  task.distal_segment_ratio: [0.1, 0.3]\n"
        "  task.object_width_m: [0.040, 0.080]\n"
        "  task.centering_position_m: [0.085, 0.115]\n"
        "simulation: {time_step_s: 4.0e-3, scale: 20, solver_iterations: 50}\n"
    )
    (folder / "ours.yaml").write_text("name: tiny_ours\n" + grid % "")
    (folder / "original.yaml").write_text("name: tiny_original\n" + grid % ", spring_scale: 2.0")
    path = folder / "ablation.yaml"
    path.write_text(
        "name: tiny_ablation\ngrids: {tiny: {ours: ours.yaml, original: original.yaml}}\n"
        "factors:\n  springs_x2: {ours: {task.spring_scale: 1.0}, original: {task.spring_scale: 2.0}}\n"
    )
    return path


def test_fig6_ablation_command_runs_missing_configurations_and_writes_the_table_and_figures(
    tmp_path: Path,
) -> None:
    ablation = tiny_ablation(tmp_path)
    args = ["paper", "fig6-ablation", "--ablation", str(ablation), "--grid", "tiny", "--jobs", "1"]
    args += ["--results-root", str(tmp_path / "results"), "--out", str(tmp_path / "out")]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    # With one factor, its one-at-a-time steps are the two ends: two folders run, eight cells each.
    assert "configuration ours (= original-springs_x2): 8 cells" in result.output
    assert "configuration original (= ours+springs_x2): 8 cells" in result.output
    for name in ("fig6_ablation.csv", "fig6_ablation.md", "fig6_ablation.png", "fig6_compare.png"):
        assert (tmp_path / "out" / name).is_file(), name
    table = pd.read_csv(tmp_path / "out" / "fig6_ablation.csv")
    assert set(table["configuration"]) == {"ours", "original", "ours+springs_x2", "original-springs_x2"}
    assert set(table["results"]) == {"tiny_ours", "tiny_original"}  # the one-factor steps are the ends
    assert (table["cells"] == 4).all()
    again = CliRunner().invoke(app, args)  # resumable: nothing left to run
    assert again.exit_code == 0 and "0 trial(s) run" in again.output


def test_make_fig6_ablation_runs_the_command() -> None:
    if shutil.which("make") is None:
        pytest.skip("make is not installed")
    out = subprocess.run(
        ["make", "-n", "fig6-ablation", "fig6-ablation-quick"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    assert "somo-sweep paper fig6-ablation --paper-style --out results/reference" in out
    assert "somo-sweep paper fig6-ablation --quick" in out
