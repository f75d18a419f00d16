"""``visnav sweep``: Monte-Carlo campaigns over scenario and gain distributions.

::

    visnav sweep [--scenario NAME|FILE] [--samples N] [--seed S] [--out DIR]
                 [--workers N | --dask-local N | --scheduler tcp://HOST:PORT]
                 [--connect-timeout S] [--no-worker-timeout S] [--json] [--progress]

Writes ``DIR/results.jsonl`` (one line per finished sample, appended and
``fsync``-ed as results arrive, each bound to the campaign by its spec hash;
see :mod:`visnav.app.campaign_store`) and, once every sample is done,
``DIR/summary.json``.  Rerunning the same command after an interruption
(Ctrl-C, ``kill -9``, a crash, a full disk, lost Dask workers) resumes the
campaign: samples already stored are not run again, and the final files are
byte-identical to those of an uninterrupted run.  One sweep at a time writes a
folder (an ``flock`` held by the process).

Exit codes: 0 the campaign completed (whatever its success rate), 2 bad input
(scenario, options, output folder, a results file of another campaign, a folder
another sweep is writing, a scheduler that does not answer within
``--connect-timeout`` or is not a Dask scheduler), 3 the run could not complete
(the executor failed, the disk is full, no Dask worker alive for
``--no-worker-timeout``, ``summary.json`` cannot be written: what is stored
stays valid, the message says what is kept, and the same command resumes),
130 interrupted (resumable).
"""

from __future__ import annotations

import argparse
import errno
import json
import math
import sys
import time
from typing import Any, TextIO

from visnav.app.cli_types import (
    EXIT_BAD_INPUT,
    EXIT_DIVERGED,
    EXIT_OK,
    non_negative_int,
    positive_int,
    positive_seconds,
)

__all__ = ["add_parser", "open_campaign_store", "EXIT_INTERRUPTED", "RESULTS_FILE", "SUMMARY_FILE", "FLAGS"]

EXIT_INTERRUPTED = 130
"""Exit code after Ctrl-C (128 + SIGINT), as shells report it."""
RESULTS_FILE = "results.jsonl"
SUMMARY_FILE = "summary.json"
DEFAULT_OUT = "out/sweep"
DEFAULT_SAMPLES = 100
DEFAULT_CONNECT_TIMEOUT_S = 10.0
DEFAULT_NO_WORKER_TIMEOUT_S = 60.0  # analysis.campaigns.DEFAULT_NO_WORKER_TIMEOUT_S (not imported: start-up time)
EXIT_COULD_NOT_COMPLETE = EXIT_DIVERGED
"""Exit code 3, "the run could not complete": what is stored stays valid and the same command resumes."""
_RESOURCE_ERRNOS = frozenset(code for code in (errno.ENOSPC, getattr(errno, "EDQUOT", None), errno.EFBIG, errno.EIO,
                                               errno.ENOMEM) if code is not None)

FLAGS = {
    "workers": "--workers",
    "dask_local": "--dask-local",
    "scheduler": "--scheduler",
    "connect_timeout_s": "--connect-timeout",
    "no_worker_timeout_s": "--no-worker-timeout",
    "samples": "--samples",
    "seed": "--seed",
}
"""The options of ``visnav sweep`` by the name of the parameter they set in :mod:`analysis.campaigns`
and :class:`visnav.studies.campaign.CampaignSpec` (their errors are shown with these names)."""


def _error_text(err: Exception) -> str:
    """The message of a campaign library error, its parameters named by their ``visnav sweep`` options."""
    from analysis.campaigns import CampaignOptionError, SchedulerUnavailableError
    from visnav.studies.campaign import CampaignSpecError

    if isinstance(err, (CampaignOptionError, SchedulerUnavailableError)):
        return err.render(FLAGS)
    if isinstance(err, CampaignSpecError) and err.parameter in FLAGS:
        return f"{FLAGS[err.parameter]} = {err.value!r}: expected {err.expected}; fix: {err.fix}"
    return str(err)


def open_campaign_store(path: Any, spec: Any) -> tuple[Any, Any]:
    """:func:`visnav.app.campaign_store.open_store` for the results file of a ``visnav sweep`` campaign.

    Parameters
    ----------
    path : path-like
        The results file.
    spec : visnav.studies.campaign.CampaignSpec
        The campaign (its header: :func:`visnav.studies.campaign.store_header`).

    Returns
    -------
    (CampaignStore, StoreReport)
    """
    from visnav.app.campaign_store import ResultCodec, StoreHints, open_store
    from visnav.studies.campaign import SampleResult, store_header

    codec = ResultCodec(to_dict=SampleResult.as_dict, from_dict=SampleResult.from_dict, index=lambda r: r.index)
    hints = StoreHints(writer="visnav sweep", out_option="--out",
                       same_campaign="the same scenario, --samples, --seed and distributions",
                       quiet_keys=("scenario_toml",))  # the scenario's digest covers its text
    return open_store(path, store_header(spec), codec, samples=spec.samples, hints=hints)


def add_parser(sub: Any) -> None:
    """Register the ``sweep`` subcommand on the subparsers ``sub`` of :func:`visnav.app.cli.build_parser`."""
    p = sub.add_parser(
        "sweep",
        help="Monte-Carlo campaign over scenario and gain distributions (resumable)",
        description="Run N perturbed copies of a scenario (start pose, obstacles, target, gains k, lambda_VS, "
        "v_coll) and summarise success rate, clearance, reconstruction error and failure classes. Rerun the "
        "same command to resume an interrupted campaign.",
    )
    p.add_argument("--scenario", default="paper", help="built-in scenario name or path to a TOML file (default: paper)")
    p.add_argument("--samples", type=positive_int, default=DEFAULT_SAMPLES,
                   help=f"number of scenarios N (default: {DEFAULT_SAMPLES})")
    p.add_argument("--seed", type=non_negative_int, default=0, help="seed; sample i depends on (seed, i) only (default: 0)")
    p.add_argument("--out", default=DEFAULT_OUT,
                   help=f"folder for {RESULTS_FILE} and {SUMMARY_FILE} (default: {DEFAULT_OUT})")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--workers", type=positive_int, default=None,
                       help="local worker processes (default: the number of CPUs; 1 runs in this process)")
    where.add_argument("--dask-local", type=positive_int, default=None, metavar="N",
                       help="run on a Dask LocalCluster of N single-threaded worker processes")
    where.add_argument("--scheduler", default=None, metavar="tcp://HOST:PORT",
                       help="run on the Dask cluster of this scheduler (its workers must have visnav installed)")
    p.add_argument("--connect-timeout", type=positive_seconds, default=DEFAULT_CONNECT_TIMEOUT_S, metavar="S",
                   help=f"seconds to reach the scheduler and find a worker (default: {DEFAULT_CONNECT_TIMEOUT_S:g})")
    p.add_argument("--no-worker-timeout", type=positive_seconds, default=DEFAULT_NO_WORKER_TIMEOUT_S, metavar="S",
                   help="with --dask-local or --scheduler: stop (exit 3, resumable) once no Dask worker has been "
                   f"alive for S seconds (default: {DEFAULT_NO_WORKER_TIMEOUT_S:g})")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of the human summary")
    p.add_argument("--progress", action="store_true", help="show the progress bar even when stderr is not a terminal")
    p.set_defaults(func=_cmd_sweep)


class _Progress:
    """A one-line progress bar on a stream (redrawn at most every 0.1 s)."""

    WIDTH = 30

    def __init__(self, stream: TextIO, total: int, done: int, enabled: bool) -> None:
        self.stream = stream
        self.total = total
        self.done = done
        self.start_done = done
        self.enabled = enabled
        self.start = time.perf_counter()
        self.last = -math.inf

    def update(self, step: int = 1) -> None:
        self.done += step
        now = time.perf_counter()
        if self.enabled and (now - self.last >= 0.1 or self.done == self.total):
            self.last = now
            self._draw(now)

    def _draw(self, now: float) -> None:
        fraction = self.done / self.total if self.total else 1.0
        filled = int(round(fraction * self.WIDTH))
        elapsed = now - self.start
        ran = self.done - self.start_done
        rate = ran / elapsed if elapsed > 0 else 0.0
        eta = f"{(self.total - self.done) / rate:5.0f} s left" if rate > 0 else "        "
        self.stream.write(f"\rsweep [{'#' * filled}{'.' * (self.WIDTH - filled)}] {self.done}/{self.total} "
                          f"{rate:6.2f}/s {eta}")
        self.stream.flush()

    def finish(self) -> None:
        if self.enabled and self.last > -math.inf:
            self.stream.write("\n")
            self.stream.flush()


def _quantile_line(pairs: dict[str, float], unit: str) -> str:
    if not pairs:
        return "(none)"
    names = {"0": "min", "0.05": "q05", "0.25": "q25", "0.5": "median", "0.75": "q75", "0.95": "q95", "1": "max"}
    return "  ".join(f"{names.get(k, k)} {v:.4g}" for k, v in pairs.items()) + f" {unit}"


def _human(out: dict[str, Any]) -> str:
    s = out["summary"]
    counts = ", ".join(f"{k} {v}" for k, v in s["counts"].items() if v)
    rate = s["success_rate"]
    lo, hi = s["success_interval_95"] or (None, None)
    lines = [
        f"sweep {out['scenario']} (seed {out['seed']}, {s['samples_requested']} samples, spec {s['spec_hash'][:12]}): "
        + ("complete" if s["complete"] else f"{s['samples_done']} done"),
        f"  executor                    {out['executor']}",
        f"  this run                    {out['ran']} samples in {out['wall_time_s']:.1f} s"
        + (f" ({out['scenarios_per_s']:.2f} scenarios/s)" if out["scenarios_per_s"] else "")
        + (f", {out['resumed']} resumed from the results file" if out["resumed"] else ""),
        f"  success rate                {rate:.4f} (95% Wilson interval [{lo:.4f}, {hi:.4f}])"
        if rate is not None else "  success rate                (no results)",
        f"  outcomes                    {counts}",
        f"  min clearance               {_quantile_line(s['clearance_quantiles_m'], 'm')}",
        f"  max reconstruction error    {_quantile_line(s['reconstruction_error_quantiles_px'], 'px')}",
        f"  final feature error         {_quantile_line(s['final_error_quantiles_px'], 'px')}",
    ]
    for name, indices in s["failures"].items():
        shown = ", ".join(str(i) for i in indices[:12]) + (", ..." if len(indices) > 12 else "")
        lines.append(f"  {name:<27} samples {shown}")
    lines += [f"  wrote {path}" for path in out["written"]]
    return "\n".join(lines)


def _error(text: str) -> None:
    print(f"visnav: error: {text}", file=sys.stderr)


def _strerror(err: OSError) -> str:
    from visnav.app.campaign_store import os_error_reason

    return os_error_reason(err)


def _free_space_hint(err: OSError) -> str:
    return "free some space" if getattr(err, "errno", None) in _RESOURCE_ERRNOS else "fix the cause"


def _cmd_sweep(args: argparse.Namespace) -> int:
    from analysis.campaigns import CampaignOptionError, NoWorkerError, SchedulerUnavailableError, campaign_executor
    from visnav.studies.campaign import PRELOAD, CampaignSpec, CampaignSpecError, run_campaign, summarise
    from visnav.app.campaign_store import CampaignStoreWriteError
    from visnav.app.files import prepare_output_dir
    from visnav.scenario import load_scenario

    scenario = load_scenario(args.scenario)  # ScenarioError: exit 2 in visnav.app.cli.main
    try:
        spec = CampaignSpec(scenario=scenario, samples=args.samples, seed=args.seed)
    except CampaignSpecError as err:
        _error(_error_text(err))
        return EXIT_BAD_INPUT
    folder = prepare_output_dir(args.out)  # OutputError: exit 2 in visnav.app.cli.main
    results_path = folder / RESULTS_FILE
    summary_path = folder / SUMMARY_FILE
    if (summary_path.exists() or summary_path.is_symlink()) and not summary_path.is_file():
        _error(f"--out {str(folder)!r}: {SUMMARY_FILE} exists and is not a file (a folder, a broken link?), so the "
               f"summary could not be written; move {summary_path} away, or choose another --out")
        return EXIT_BAD_INPUT
    opened = _open_store(results_path, folder, spec)
    if isinstance(opened, int):
        return opened
    store, report = opened
    _warn_store_report(results_path, report)
    resumed = report.results
    with store:  # closing never raises: every line was fsync-ed when it was appended
        progress = _Progress(sys.stderr, spec.samples, resumed, args.progress or sys.stderr.isatty())

        def sink(result: Any) -> None:
            store.append(result)
            progress.update()

        def kept() -> str:
            return f"{len(store.done)} of {spec.samples} samples are stored in {results_path}"

        start = time.perf_counter()
        description = "none needed (every sample was already stored)"
        try:
            if len(store.done) < spec.samples:
                with campaign_executor(workers=args.workers, dask_local=args.dask_local, scheduler=args.scheduler,
                                       connect_timeout_s=args.connect_timeout,
                                       no_worker_timeout_s=args.no_worker_timeout, preload=PRELOAD) as backend:
                    description = backend.description
                    run_campaign(spec, backend.executor, sink, skip=store.done, window=backend.window)
        except (CampaignOptionError, SchedulerUnavailableError) as err:
            progress.finish()
            _error(_error_text(err))
            return EXIT_BAD_INPUT
        except KeyboardInterrupt:
            progress.finish()
            print(f"visnav: interrupted: {kept()}; rerun the same command to resume", file=sys.stderr)
            return EXIT_INTERRUPTED
        except CampaignStoreWriteError as err:
            progress.finish()
            _error(f"the campaign stopped: {err.action} to {results_path} failed ({err.cause}); {kept()}, valid; "
                   f"{_free_space_hint(err)} and rerun the same command to resume")
            return EXIT_COULD_NOT_COMPLETE
        except NoWorkerError as err:
            progress.finish()
            _error(f"the campaign stopped: {err.render(FLAGS)}; {kept()}; start Dask workers (`dask worker ADDRESS`) "
                   "or raise --no-worker-timeout, and rerun the same command to resume")
            return EXIT_COULD_NOT_COMPLETE
        except Exception as err:  # noqa: BLE001 - an executor or worker failure, reported with the resume hint
            progress.finish()
            reason = " ".join(str(err).split())
            _error(f"the campaign stopped ({type(err).__name__}{': ' + reason if reason else ''}); {kept()}; rerun "
                   "the same command to resume")
            return EXIT_COULD_NOT_COMPLETE
        wall = time.perf_counter() - start
        progress.finish()
        try:
            store.compact()
        except CampaignStoreWriteError as err:
            _error(f"every sample is done, but {err.action} failed ({err.cause}"
                   + (f"; it needs about {err.needed_bytes} bytes free" if err.needed_bytes else "")
                   + f"): {results_path} is kept as it was, complete and valid (all {spec.samples} samples, in the "
                   f"order they finished); {_free_space_hint(err)} and rerun the same command: it runs nothing again, "
                   f"puts the file in index order and writes {SUMMARY_FILE}")
            return EXIT_COULD_NOT_COMPLETE
        summary = summarise(spec, store.results())
        try:  # still holding the lock: no other sweep of this folder writes the summary meanwhile
            out = _write_summary(folder, spec, summary, description=description, resumed=resumed, wall=wall,
                                 dropped=[str(bad) for bad in report.bad_lines])
        except OSError as err:
            _error(f"every sample is done, but {summary_path} could not be written ({_strerror(err)}): "
                   f"{results_path} is complete and valid (all {spec.samples} samples); {_free_space_hint(err)} and "
                   f"rerun the same command: it runs nothing again and writes {SUMMARY_FILE}")
            return EXIT_COULD_NOT_COMPLETE
    print(json.dumps(out, sort_keys=True) if args.json else _human(out))
    return EXIT_OK


def _open_store(results_path: Any, folder: Any, spec: Any) -> tuple[Any, Any] | int:
    """The campaign's result store and its load report, or the exit code when it cannot be opened (the error
    said)."""
    from visnav.app.campaign_store import CampaignStoreError, CampaignStoreWriteError

    try:
        return open_campaign_store(results_path, spec)
    except CampaignStoreError as err:
        _error(str(err))
        return EXIT_BAD_INPUT
    except CampaignStoreWriteError as err:
        _error(f"{err}; {_free_space_hint(err)} and rerun the same command (nothing was run)")
        return EXIT_COULD_NOT_COMPLETE if err.resource else EXIT_BAD_INPUT
    except OSError as err:
        if err.errno in _RESOURCE_ERRNOS:
            _error(f"--out {str(folder)!r}: cannot write {RESULTS_FILE} ({_strerror(err)}); nothing was run; free "
                   "some space and rerun the same command")
            return EXIT_COULD_NOT_COMPLETE
        _error(f"--out {str(folder)!r}: cannot write {RESULTS_FILE} ({_strerror(err)}); choose a writable folder")
        return EXIT_BAD_INPUT


def _warn_store_report(results_path: Any, report: Any) -> None:
    """Warn on stderr about what loading the result store changed (migrated file, dropped bad lines)."""
    if report.migrated:
        print(f"visnav: warning: {results_path}: written by an older visnav (lines without the campaign's spec hash); "
              f"its {report.results} results were bound to this campaign and the file rewritten in the current format",
              file=sys.stderr)
    for bad in report.bad_lines:
        print(f"visnav: warning: {results_path}: {bad}; dropped", file=sys.stderr)
    if report.bad_lines:
        print(f"visnav: warning: {results_path}: kept {report.results} valid results and rewrote the file without "
              f"the {len(report.bad_lines)} bad line(s); their samples will be run again", file=sys.stderr)


def _write_summary(folder: Any, spec: Any, summary: Any, *, description: str, resumed: int, wall: float,
                   dropped: list[str]) -> dict[str, Any]:
    """Write ``summary.json`` (the campaign without its scenario text, and the summary); return the output object."""
    from visnav.app.files import write_text_atomic

    campaign = {k: v for k, v in spec.as_dict().items() if k != "scenario_toml"}
    summary_dict = summary.as_dict()
    write_text_atomic(folder / SUMMARY_FILE,
                      json.dumps({"campaign": campaign, "summary": summary_dict}, indent=2, sort_keys=True) + "\n")
    ran = spec.samples - resumed
    results_path = folder / RESULTS_FILE
    return {
        "scenario": spec.scenario.name,
        "seed": spec.seed,
        "executor": description,
        "ran": ran,
        "resumed": resumed,
        "dropped_lines": dropped,
        "wall_time_s": wall,
        "scenarios_per_s": ran / wall if ran and wall > 0 else None,
        "results_file": str(results_path),
        "summary_file": str(folder / SUMMARY_FILE),
        "written": [str(results_path), str(folder / SUMMARY_FILE)],
        "summary": summary_dict,
    }
