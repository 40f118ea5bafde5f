"""``ipfit batch INPUT... -o OUTDIR``: fit many shapes on Dask (embedded cluster or --scheduler)."""

from __future__ import annotations

import argparse
import logging
import signal
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING

from ._common import cli_names, positive_int
from .fit import _OPTION_NAMES, _parse_degree, add_fit_options, search_settings

if TYPE_CHECKING:
    from rich.progress import Progress, TaskID

NAME = "batch"
HELP = "fit many shapes in parallel on Dask (files, folders, globs, bundled names)"
DESCRIPTION = """\
Fit every shape of INPUT... (point files, folders of point files, quoted globs, bundled dataset
names, or generated:N[:SEED] for N shapes of ipfit's generated collection) with the same fit
options as `ipfit fit`, in parallel on Dask:

  embedded (default)     a local cluster of --workers processes, one BLAS thread each,
                         started and stopped with the command
  --scheduler ADDRESS    an existing cluster (tcp://host:8786); ipfit must be importable there

OUTDIR receives NAME.json per shape (the result JSON of `ipfit fit`) and summary.csv (and
summary.parquet with pyarrow): one row per shape with its seed, points, selected degree,
measures, F-score, spurious components, seconds, status (ok, skipped, failed, cancelled) and
error. With --html: NAME.html and a NAME.png thumbnail per shape, index.html, and the one
plotly.min.js the pages share. Dask's own warnings go to OUTDIR/batch.log. A batch with
nothing left to do starts no cluster.

NAME is the file's stem (a.ply -> a), the dataset's or the generated shape's name. Where two
shapes share a name (ignoring case), or for the reserved names summary and index, a file's
NAME is its file name with dashes (a.ply -> a-ply, a.xyz -> a-xyz), and a name that still
clashes gets 6 hex digits of a hash of its path (a-ply-3f2a9c): names depend on the set of
inputs, never on their order. A file given twice (a folder and a glob) is fitted once.

Shape NAME is fitted with its own seed, made from --seed and NAME and written in summary.csv's
seed column: `ipfit fit FILE --seed SEED` with the batch's other fit options gives its result
again, bit for bit, as does any batch on any worker. A shape whose result in
OUTDIR is valid, of the same file and settings is skipped: re-running after a crash or Ctrl-C
finishes the rest (a damaged result is fitted again). A shape that cannot be read or fitted,
or whose worker dies, is a failed row; the rest go on. Ctrl-C cancels the pending shapes,
keeps the finished results, writes the summary, stops the workers and exits with 130.

OUTDIR/.ipfit-batch.json lists the files the batch writes there; before any work, the batch
refuses to replace a file that is not listed (for NAME.json: nor an ipfit result) or that
is an input. Limits, checked first: generated:N up to 10,000 shapes; --workers up to 4 per
core and one per 512 MiB of available memory; --scheduler must answer within 10 s
(IPFIT_BATCH_CONNECT_TIMEOUT). A FIFO or device is refused (skipped in folders and globs).
Needs dask.distributed: pip install 'ipfit[dask]'.
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("inputs", nargs="+", metavar="INPUT", help="point files, folders, globs, bundled names, "
                        "generated:N[:SEED]")
    parser.add_argument("-o", "--output", required=True, metavar="OUTDIR", help="folder for the results")
    where = parser.add_mutually_exclusive_group()
    where.add_argument("--workers", type=positive_int, default=None, metavar="N",
                       help="worker processes of the embedded cluster (default 2; at most 4 per core "
                       "and one per 512 MiB of available memory)")
    where.add_argument("--scheduler", metavar="ADDRESS", help="use the Dask scheduler at ADDRESS instead")
    add_fit_options(parser)
    parser.add_argument("--html", action="store_true",
                        help="also write NAME.html (the viewer) and NAME.png (a thumbnail) per shape, and "
                        "index.html linking them all")
    parser.add_argument("-q", "--quiet", action="store_true", help="no progress output")


class BatchProgress:
    """Shapes done / failed / running and the ETA: a rich bar on a TTY, a line per shape when piped."""

    def __init__(self, mode: str, stream=None) -> None:
        self.mode, self.stream = mode, sys.stderr if stream is None else stream
        self._bar: Progress | None = None
        self._task: TaskID | None = None

    def __call__(self, event: dict) -> None:
        if self.mode == "off":
            return
        finished = event["done"] + event["failed"] + event["skipped"]
        eta = "?" if event["eta"] is None else f"{event['eta']:.0f} s"
        counts = f"{event['done']} done, {event['failed']} failed, {event['running']} running, ETA {eta}"
        if self.mode == "bar":
            if self._bar is None:
                from rich.console import Console
                from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

                self._bar = Progress(TextColumn("batch"), BarColumn(), MofNCompleteColumn(),
                                     TextColumn("{task.fields[counts]}"), TimeElapsedColumn(),
                                     console=Console(file=self.stream), transient=True)
                self._bar.start()
                self._task = self._bar.add_task("batch", total=event["total"], counts=counts)
            self._bar.update(self._bar_task(), completed=finished, counts=counts)
            if event["status"] == "failed":
                self._bar.console.print(f"{event['name']}: failed: {event['error']}")
            return
        error = f": {event['error']}" if event["status"] == "failed" else ""
        self.stream.write(f"[{finished}/{event['total']}] {event['name']}: {event['status']}{error}; {counts}\n")
        self.stream.flush()

    def _bar_task(self) -> TaskID:
        """The bar's task, which an open bar always has (both are set together)."""
        if self._task is None:
            raise RuntimeError("BatchProgress: a bar without its task")  # a bug of ipfit's
        return self._task

    def close(self) -> None:
        if self._bar is not None:
            self._bar.stop()
            self._bar = None


#: What --html adds to OUTDIR (checked and recorded with the batch's own outputs): plotly's
#: script once, shared by the pages.
HTML_FILES = ("{name}.html", "{name}.png", "index.html", "plotly.min.js")
#: A batch page's mesh budget, shared by the degrees it shows, and its data points: with plotly's
#: script shared, a page of four 3D degrees is then about 0.7 MB (a shape's own `ipfit view`
#: page draws up to 15,000 faces per degree and 40,000 points).
PAGE_FACES = 16_000
PAGE_POINTS = 5_000
#: Dask's own warnings during the batch (a busy port, ...), when it gave any.
LOG_FILE = "batch.log"


def _page_is_current(page: Path, thumbnail: Path, result_file: Path) -> bool:
    """Whether a skipped shape's page and thumbnail are this batch's, newer than its result, and
    load the shared script (pages of older versions inlined it): then they are not drawn again."""
    from ..viz.viewer import PLOTLY_SCRIPT

    try:
        if min(page.stat().st_mtime_ns, thumbnail.stat().st_mtime_ns) < result_file.stat().st_mtime_ns:
            return False
        with page.open("rb") as fh:
            head = fh.read(4096)
    except OSError:
        return False
    return f'src="{PLOTLY_SCRIPT}"'.encode() in head


def write_viewers(folder: Path, batch) -> Path:
    """NAME.html and a NAME.png thumbnail per fitted shape, index.html linking them, and the one
    plotly.min.js they share. A skipped shape's page and thumbnail, when current, are kept."""
    from .._utils.atomic import write_text_atomic
    from ..batch import write_thumbnail
    from ..datasets.loading import load
    from ..exceptions import IpfitError
    from ..viz.viewer import PLOTLY_SCRIPT, index_page, write_html, write_plotly_script

    entries = []
    for row in batch.rows:
        result = batch.results.get(row["name"])
        if row["status"] not in ("ok", "skipped") or result is None:
            continue
        name = row["name"]
        page, thumbnail = folder / f"{name}.html", folder / f"{name}.png"
        if not (row["status"] == "skipped" and _page_is_current(page, thumbnail, folder / f"{name}.json")):
            source = (result.get("input") or {}).get("path") or row.get("input")
            try:
                data = load(str(source)) if source else None
            except IpfitError:  # generated shapes and moved files: the viewer frames the result without its points
                data = None
            points = None if data is None else data.points
            faces_per_degree = max(500, PAGE_FACES // max(1, len(result.get("degrees") or ())))
            write_html(result, points, page, include_plotlyjs=PLOTLY_SCRIPT, max_faces=faces_per_degree,
                       max_points=PAGE_POINTS)
            write_thumbnail(result, points, thumbnail, faces=None if data is None else data.faces)
        f_score = row.get("f_score")
        caption = f"degree {row.get('selected_degree')}" + (f", F = {f_score:.3f}" if f_score is not None else "")
        entries.append((name, page.name, thumbnail.name, caption))
    if not (folder / PLOTLY_SCRIPT).is_file() or any(row["status"] == "ok" for row in batch.rows):
        write_plotly_script(folder)
    index = folder / "index.html"
    write_text_atomic(index, index_page(f"ipfit batch: {len(entries)} shapes", entries))
    return index


class _Collected(logging.Handler):
    """Keeps the records of the batch's logger (Dask's warnings), to be written once at the end."""

    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.lines: list[str] = []
        self.setFormatter(logging.Formatter("%(asctime)s %(levelname)s %(message)s"))

    def emit(self, record: logging.LogRecord) -> None:
        self.lines.append(self.format(record))


def run(args: argparse.Namespace) -> int:
    from .._utils.atomic import write_text_atomic
    from ..batch import LOGGER, fit_many
    from ._progress import progress_mode

    degree = _parse_degree(args.degree, 0)
    method, options, rule = search_settings(args)
    outliers = "none" if args.paper else ("auto" if args.outliers is None else args.outliers)
    shown = BatchProgress(progress_mode(args.quiet))
    start = time.perf_counter()
    # Dask's warnings go to OUTDIR/batch.log, not to the terminal (the library logs them)
    collected, logger = _Collected(), logging.getLogger(LOGGER)
    logger.addHandler(collected)
    try:
        with cli_names({**_OPTION_NAMES, "inputs": "INPUT", "workers": "--workers"}):
            batch = fit_many(args.inputs, workers=args.workers, scheduler=args.scheduler, output=args.output,
                             method=method, options=options, rule=rule, epsilon=args.epsilon, delta=args.delta,
                             min_degree=degree or 2, max_degree=degree or args.max_degree, seed=args.seed,
                             outliers=outliers, progress=shown,
                             also_writes=(LOG_FILE, *(HTML_FILES if args.html else ())))
    finally:
        shown.close()
        logger.removeHandler(collected)
    folder = Path(args.output)
    written = [folder / "summary.csv"]
    if collected.lines:
        write_text_atomic(folder / LOG_FILE, "\n".join(collected.lines) + "\n")
        written.append(folder / LOG_FILE)
    counts = batch.counts()
    if args.html:
        written.append(write_viewers(folder, batch))
    if not args.quiet:
        summary = ", ".join(f"{n} {status}" for status, n in sorted(counts.items()))
        log = f" (Dask's warnings: {folder / LOG_FILE})" if collected.lines else ""
        print(f"{len(batch.rows)} shapes: {summary} in {time.perf_counter() - start:.1f} s; "
              f"wrote {', '.join(map(str, written))}" + (" and a page per shape" if args.html else "") + log)
    if batch.interrupted:
        print(f"ipfit batch: interrupted; kept {counts.get('ok', 0)} finished results in {args.output}, "
              "summary written; run the same command again to finish the rest", file=sys.stderr)
        return 128 + (batch.signal or signal.SIGINT)
    return 0  # failed shapes are rows of the summary, not a failure of the command
