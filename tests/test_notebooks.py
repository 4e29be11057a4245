"""The notebooks (jupytext percent files in notebooks/) execute against the smoke reproduction,
and against the same runs shipped into a data folder (`curious ship`).

Each notebook is read with jupytext, given the smoke output folder (or the shipped data folder)
as its `out` parameter the way papermill does it (a cell injected after the one tagged
`parameters`), and executed with nbclient in a fresh kernel from the notebooks folder.
"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import jupytext
import nbformat
import pytest
from nbclient import NotebookClient

from curious.reproduction.experiments import DEFAULT_BUDGET, get_budget

NOTEBOOKS = Path(__file__).resolve().parent.parent / "notebooks"
NAMES = (
    "main_comparison",
    "developmental_phases",
    "forgetting_and_sensor_failure",
    "distractors",
    "beyond_the_paper",
)


def parameters_cell(nb: nbformat.NotebookNode) -> int:
    tagged = [i for i, c in enumerate(nb.cells) if "parameters" in c.metadata.get("tags", [])]
    assert len(tagged) == 1, "a notebook has exactly one cell tagged `parameters`"
    return tagged[0]


def test_every_notebook_is_listed_and_defaults_to_the_quick_output():
    assert sorted(p.stem for p in NOTEBOOKS.glob("*.py")) == sorted(NAMES)
    default = get_budget(DEFAULT_BUDGET).default_out
    for name in NAMES:
        nb = jupytext.read(NOTEBOOKS / f"{name}.py")
        assert f'out = "{default}"' in nb.cells[parameters_cell(nb)].source


def execute(name: str, out: Path) -> list[nbformat.NotebookNode]:
    """Run notebook `name` with `out` as its output folder; the outputs of its code cells."""
    nb = jupytext.read(NOTEBOOKS / f"{name}.py")
    injected = nbformat.v4.new_code_cell(
        f"out = {str(out)!r}", metadata={"tags": ["injected-parameters"]}
    )
    nb.cells.insert(parameters_cell(nb) + 1, injected)
    client = NotebookClient(
        nb,
        timeout=300,
        kernel_name="python3",
        resources={"metadata": {"path": str(NOTEBOOKS)}},
    )
    client.execute()  # raises CellExecutionError, with the cell and traceback, on any error
    outputs = [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])]
    assert not [o for o in outputs if o.get("output_type") == "error"]
    return outputs


@pytest.mark.parametrize("name", NAMES)
def test_notebook_executes_against_the_smoke_output_and_its_shipped_data(name, smoke, shipped):
    """The notebook runs on the smoke output and draws figures; with `out` set to the same runs
    shipped into a data folder, it runs on the shipped tables alone and draws the same figures,
    byte for byte, and prints the same text (outputs that name a run folder aside: its path
    differs)."""
    assert shipped.source.out == smoke.out
    base = os.path.commonpath([smoke.out, shipped.data])  # the temp folder above both

    def shown(outputs: list[nbformat.NotebookNode]) -> tuple[list[str], list[str], int]:
        images, texts, with_paths = [], [], 0
        for o in outputs:
            data = o.get("data", {})
            if "image/png" in data:
                images.append(data["image/png"])
                continue
            text = o.get("text", "") + data.get("text/plain", "")
            if base in text:
                with_paths += 1
            else:
                texts.append(text)
        return images, texts, with_paths

    from_runs = shown(execute(name, smoke.out))
    from_data = shown(execute(name, shipped.data))
    assert from_runs[0], f"{name} drew no figure"
    assert from_data == from_runs


def quick_copy(smoke, tmp_path: Path, without: tuple[str, ...]) -> Path:
    """The smoke output copied without the runs `without` names (no locks, Dagster state,
    recordings or checkpoints) and relabelled as made by `quick`: what a quick output holds."""
    out = tmp_path / "quick"
    left = (*without, "*.lock", ".dagster", "*.rrd", "checkpoints")
    shutil.copytree(smoke.out, out, ignore=shutil.ignore_patterns(*left))
    (out / "reproduce.json").write_text(json.dumps({"version": 1, "budget": "quick"}))
    return out


def stream_text(outputs: list[nbformat.NotebookNode]) -> str:
    """What the notebook's cells printed, in order."""
    return "".join(o.get("text", "") for o in outputs if o.get("output_type") == "stream")


def test_forgetting_notebook_runs_on_a_quick_output_without_the_sensory_failure(smoke, tmp_path):
    """The quick budget trains neither sensory-failure experiment: parts 1 and 2 say why and
    skip, part 3 (spontaneous forgetting) runs.

    The smoke output, copied without its sensor_failure runs and relabelled as made by `quick`,
    stands for a quick output folder.
    """
    out = quick_copy(smoke, tmp_path, ("sensor_failure*",))
    outputs = execute("forgetting_and_sensor_failure", out)
    printed = stream_text(outputs)
    quick = get_budget("quick")
    assert printed == "".join(
        f"{out.resolve()} holds no {e} runs, so part {part} is skipped. {quick.why_absent(e)}\n"
        for part, e in ((1, "sensor_failure"), (2, "sensor_failure_mastered"))
    ) + "".join(f"depth {d:g}: 0 dips, {{}}\n" for d in (0.1, 0.05))  # smoke runs master nothing
    tables = [o["data"]["text/plain"] for o in outputs if "text/plain" in o.get("data", {})]
    # part 3's three tables, and only those: the deepest falls per run and module, the drops,
    # and the runs the dips' test leaves out for a longer run of their seed (smoke's long run
    # of seed 0, shorter than its main run)
    assert len(tables) == 3 and "push_cube1" in tables[0] and "drop_episode" in tables[1]
    assert "left out of the test" in tables[2] and "kept_episodes" in tables[2]


def test_the_beyond_the_paper_notebook_says_why_a_quick_output_has_neither_part(smoke, tmp_path):
    """The quick budget trains neither `lp_uses` nor `signed_lp`: each part says why and draws
    nothing. The smoke output without those runs, relabelled as made by `quick`, stands for it."""
    out = quick_copy(smoke, tmp_path, ("lp_uses", "signed_lp"))
    outputs = execute("beyond_the_paper", out)
    printed = stream_text(outputs)
    quick = get_budget("quick")
    assert printed == "".join(
        f"{out.resolve()} holds no {e} runs, so part {part} is skipped. {quick.why_absent(e)}\n"
        for part, e in ((1, "lp_uses"), (2, "signed_lp"))
    )
    assert not [o for o in outputs if o.get("data")]  # no figure, no table


def test_the_documented_default_viewer_setting_opens_py_files_as_notebooks(tmp_path):
    """notebooks/README.md tells JupyterLab users to run `jupytext-config set-default-viewer
    python`; with the installed jupytext it writes the setting JupyterLab reads."""
    import json
    import shutil
    import subprocess

    command = shutil.which("jupytext-config")
    assert command, "jupytext-config comes with the notebooks extra"
    settings = tmp_path / "overrides.json"
    subprocess.run(
        [command, "--settings-file", str(settings), "set-default-viewer", "python"], check=True
    )
    viewers = json.loads(settings.read_text())["@jupyterlab/docmanager-extension:plugin"]
    assert viewers["defaultViewers"]["python"] == "Jupytext Notebook"
    readme = (Path(__file__).resolve().parents[1] / "notebooks" / "README.md").read_text()
    assert "jupytext-config set-default-viewer python" in readme
