"""The Dagster assets of one budget, one asset group per experiment.

For every experiment E (`curious.reproduction.experiments`), in group E:

* `E/runs`: the training runs, partitioned by `condition` x `seed` (one partition = one run
  folder). One Dagster run materialises a whole range of partitions (single-run backfill
  policy) and trains them side by side on the pool; a partition whose folder already holds the
  finished run is not retrained, an interrupted one resumes from its checkpoint. Reading
  shipped data (`curious reproduce --from-data`), it trains nothing: it checks that every
  partition's run is shipped and finished (`pipelines.from_data`).
* `E/metrics`: the combined metrics table of the experiment's runs
  (`curious.analysis.load_runs`), written to `metrics/E.parquet`, and their test rollouts
  (`curious.analysis.load_tests`) to `metrics/E.tests.parquet` where every run has them.
* `E/NAME`: one asset per figure registered for E (`curious.reproduction.figures`, a plugin's
  among them), drawn from those tables and saved as `figures/NAME.png` and `.svg`: the built-in
  ones `main/fig2a` (from the test rollouts, as the paper's), `main/fig2b`, `main/fig2c`,
  `main/table1`, `distractors/distractors`, `sensor_failure/sensor_failure`,
  `sensor_failure_mastered/sensor_failure_mastered` (the same figure of its own runs, with their
  test success above: the primary measure of that study) and `long/long_runs`.

And `report` (group `report`): `report.md` from the figures and statistics that exist.
"""

import base64
import warnings
from pathlib import Path

import dagster as dg
import pandas as pd
from dagster import AssetExecutionContext

from curious.reproduction.experiments import Experiment, experiment_names
from curious.reproduction.figures import FigureInputs, FigureSpec, check_figures, figures_of
from pipelines.resources import Reproduction
from pipelines.training import FINISHED, run_folder

RESOURCE = "reproduction"


def _path(repro: Reproduction, path: Path) -> dg.MetadataValue:
    """A path in asset metadata, relative to the output folder where it lies inside it, so that
    the metadata stays true when the folder is moved or shared."""
    path = Path(path)
    try:
        return dg.MetadataValue.path(
            path.resolve().relative_to(repro.layout.out.resolve()).as_posix()
        )
    except ValueError:  # outside it (--runs-dir on shared storage)
        return dg.MetadataValue.path(str(path))


def _inline_png(path: Path) -> dg.MetadataValue:
    """The figure itself, as markdown with the PNG inlined as a data URI.

    The Dagster UI draws markdown metadata of under 1000 characters in the metadata table and
    longer markdown, such as this, behind a "[Show Markdown]" link that opens it in a dialog,
    where the figure shows. In the table itself a figure would need a URL the browser can load
    (a path on this machine is not one), served by something other than Dagster.
    """
    data = base64.b64encode(Path(path).read_bytes()).decode("ascii")
    return dg.MetadataValue.md(f"![{Path(path).stem}](data:image/png;base64,{data})")


def partitions_of(experiment: Experiment) -> dg.MultiPartitionsDefinition:
    """`condition` x `seed` for one experiment (the condition axis may carry the variant)."""
    return dg.MultiPartitionsDefinition(
        {
            "condition": dg.StaticPartitionsDefinition(list(experiment.condition_keys)),
            "seed": dg.StaticPartitionsDefinition(list(experiment.seed_keys)),
        }
    )


def runs_key(experiment: str) -> dg.AssetKey:
    return dg.AssetKey([experiment, "runs"])


def metrics_key(experiment: str) -> dg.AssetKey:
    return dg.AssetKey([experiment, "metrics"])


def figure_key(experiment: str, name: str) -> dg.AssetKey:
    return dg.AssetKey([experiment, name])


def _runs_asset(experiment: Experiment) -> dg.AssetsDefinition:
    name = experiment.name

    @dg.asset(
        key=runs_key(name),
        group_name=name,
        partitions_def=partitions_of(experiment),
        backfill_policy=dg.BackfillPolicy.single_run(),
        required_resource_keys={RESOURCE},
        description=(
            f"{experiment.title}. One run folder per partition (condition x seed), trained with "
            f"the `{experiment.train_preset}` training preset for {experiment.total_episodes:,} "
            "episodes; finished runs are kept, interrupted ones resume."
        ),
        kinds={"python"},
    )
    def runs(context: AssetExecutionContext) -> dg.MaterializeResult:
        repro: Reproduction = getattr(context.resources, RESOURCE)
        order = {s.partition_key: i for i, s in enumerate(experiment.runs())}  # seed by seed
        specs = sorted(
            (experiment.run(str(key)) for key in context.partition_keys),
            key=lambda s: order[s.partition_key],
        )
        results = repro.train(experiment, specs)
        trained = [r for r in results if r.trained]
        shipped = {} if repro.data is None else {"shipped_data": _path(repro, repro.data.path)}
        return dg.MaterializeResult(
            metadata={
                "runs_root": _path(repro, repro.layout.experiment_runs(name)),
                "partitions": len(results),
                "trained": len(trained),
                "already_finished": len(results) - len(trained),
                "train_seconds": round(sum(r.seconds for r in trained), 1),
                **shipped,
            }
        )

    return runs


def load_metrics(repro: Reproduction, experiment: str) -> pd.DataFrame:
    """The combined metrics table an experiment's `metrics` asset wrote."""
    path = repro.layout.metrics(experiment)
    if not path.is_file():
        raise FileNotFoundError(f"{path} does not exist: materialise {experiment}/metrics first")
    return pd.read_parquet(path)


def run_folders(repro: Reproduction, experiment: Experiment) -> list[Path]:
    """The run folders of an experiment, in its partition order."""
    return [run_folder(s, repro.layout.runs_root) for s in experiment.runs()]


def load_tests(repro: Reproduction, experiment: Experiment) -> pd.DataFrame:
    """The combined test rollouts the `metrics` asset wrote; where it wrote none (a run without
    test rollouts), reading the run folders raises the `AnalysisError` that names that run."""
    from curious import analysis

    path = repro.layout.tests(experiment.name)
    if path.is_file():
        return pd.read_parquet(path)
    return analysis.load_tests(run_folders(repro, experiment))


def _write_table(table: pd.DataFrame, path: Path) -> None:
    """Write a parquet table atomically (a temporary file renamed over it)."""
    tmp = path.with_name(f".{path.name}.tmp")
    table.to_parquet(tmp, index=False)
    tmp.replace(path)


def _metrics_asset(experiment: Experiment) -> dg.AssetsDefinition:
    name = experiment.name

    @dg.asset(
        key=metrics_key(name),
        group_name=name,
        deps=[runs_key(name)],
        required_resource_keys={RESOURCE},
        description=(
            f"Every episode of every {name} run in one table (curious.analysis.load_runs), "
            f"written to metrics/{name}.parquet; their test rollouts "
            f"(curious.analysis.load_tests) to metrics/{name}.tests.parquet."
        ),
        kinds={"pandas", "parquet"},
    )
    def metrics(context: AssetExecutionContext) -> dg.MaterializeResult:
        from curious import analysis

        repro: Reproduction = getattr(context.resources, RESOURCE)
        layout = repro.layout
        specs = experiment.runs()
        unfinished = [s.label for s in specs if repro.run_state(s) != FINISHED]
        if unfinished:
            raise RuntimeError(
                f"{len(unfinished)} run(s) of {name} are not finished ({', '.join(unfinished)}): "
                f"materialise {name}/runs first"
            )
        folders = run_folders(repro, experiment)
        table = analysis.load_runs(folders)
        layout.metrics_dir.mkdir(parents=True, exist_ok=True)
        path = layout.metrics(name)
        _write_table(table, path)
        try:
            tests = analysis.load_tests(folders)
        except analysis.AnalysisError as exc:  # runs trained without test rollouts
            layout.tests(name).unlink(missing_ok=True)
            test_rollouts = f"none: {exc}"
        else:
            _write_table(tests, layout.tests(name))
            test_rollouts = f"{len(tests)} in metrics/{name}.tests.parquet"
        runs = analysis.runs_table(table)
        return dg.MaterializeResult(
            metadata={
                "path": _path(repro, path),
                "runs": len(runs),
                "rows": len(table),
                "episodes_per_run": int(runs["n_episodes"].max()),
                "test_rollouts": dg.MetadataValue.text(test_rollouts),
            }
        )

    return metrics


def figure_inputs(
    repro: Reproduction, experiment: Experiment, spec: FigureSpec, table: pd.DataFrame
) -> FigureInputs:
    """What a figure of `experiment` is drawn from, with the budget's caption note."""
    return FigureInputs(
        experiment=experiment,
        metrics=table,
        folders=tuple(run_folders(repro, experiment)),
        shown_anyway=tuple(repro.left_out_runs(experiment)),
        note=repro.budget.caption_note_for(experiment),
        out_dir=repro.layout.figures,
        stem=spec.stem(experiment.name),
        load_tests=lambda: load_tests(repro, experiment),
        load_other=repro.layout.read_tables,
    )


def _figure_asset(experiment: Experiment, spec: FigureSpec) -> dg.AssetsDefinition:
    stem = spec.stem(experiment.name)

    @dg.asset(
        key=figure_key(experiment.name, spec.name),
        group_name=experiment.name,
        deps=[metrics_key(name) for name in (experiment.name, *spec.reads)],
        required_resource_keys={RESOURCE},
        description=f"figures/{stem}.png and .svg, drawn by {spec.draw.__module__}.",
        kinds={"matplotlib"},
    )
    def figure(context: AssetExecutionContext) -> dg.MaterializeResult:
        from curious.analysis.style import save_figure

        repro: Reproduction = getattr(context.resources, RESOURCE)
        table = load_metrics(repro, experiment.name)
        out_dir = repro.layout.figures
        out_dir.mkdir(parents=True, exist_ok=True)
        inputs = figure_inputs(repro, experiment, spec, table)
        fig = spec.draw(inputs)
        save_figure(fig, out_dir, stem)
        caption = " ".join(fig.get_supxlabel().split())  # unwrapped
        repro.say(f"  figure: {out_dir / stem}.png")
        return dg.MaterializeResult(
            metadata={
                "figure": _inline_png(out_dir / f"{stem}.png"),
                "png": _path(repro, out_dir / f"{stem}.png"),
                "svg": _path(repro, out_dir / f"{stem}.svg"),
                "caption": dg.MetadataValue.text(caption),
                **{suffix: _path(repro, path) for suffix, path in inputs.written.items()},
            }
        )

    return figure


def _report_asset(experiments: list[Experiment]) -> dg.AssetsDefinition:
    @dg.asset(
        key="report",
        group_name="report",
        deps=[figure_key(e.name, f.name) for e in experiments for f in figures_of(e.name)],
        required_resource_keys={RESOURCE},
        description="report.md: the figures, seeds, budgets and statistics (Welch tests).",
        kinds={"markdown"},
    )
    def report(context: AssetExecutionContext) -> dg.MaterializeResult:
        from pipelines.report import write_report

        repro: Reproduction = getattr(context.resources, RESOURCE)
        path, included = write_report(repro)
        return dg.MaterializeResult(
            metadata={
                "path": _path(repro, path),
                "experiments": ", ".join(included),
            }
        )

    return report


def experiment_assets(experiment: Experiment) -> list[dg.AssetsDefinition]:
    """The runs, metrics and figure assets of one experiment."""
    return [
        _runs_asset(experiment),
        _metrics_asset(experiment),
        *(_figure_asset(experiment, spec) for spec in figures_of(experiment.name)),
    ]


def all_assets(experiments: list[Experiment]) -> list[dg.AssetsDefinition]:
    """Every experiment's assets and the report; a `ValueError` where a registered figure names
    an experiment that does not exist."""
    check_figures(experiment_names())
    with warnings.catch_warnings():
        # `backfill_policy` is marked beta in Dagster 1.13; single-run backfills are what lets
        # one run train many partitions side by side.
        warnings.simplefilter("ignore", dg.BetaWarning)
        assets = [a for e in experiments for a in experiment_assets(e)]
        return [*assets, _report_asset(experiments)]
