"""What each input of an ingest is, by its content: a log container, a CAN log, an NMEA capture, a DCA1000 capture,
or a drive folder, and the inputs sorted by kind.

A drive folder is a directory that holds one drive's inputs of several kinds (a ROS log beside the CAN logger's
files, an NMEA capture, a DCA1000 capture's files): each is read as if it were given on its own, a capture's files
lying in the folder itself being the folder read as that capture, and a folder inside it that holds inputs (the CAN
logger's ``can/``) giving those. A directory stays what it was (a rosbag2 bag, its
``metadata.yaml`` or its storage files alone; a DCA1000 capture's files alone) unless it holds a CAN log or an NMEA
capture, a capture's files beside a log, a log no bag's storage file is (a ROS 1 bag, a bag's own folder, a
simulated MCAP beside its truth sidecar), or a
capture's own folder: read as a bag, its other files went unread without a word. What a drive folder
holds that is none of those (a text file, a table, a folder of its own) is named in a warning and left alone;
autosar's own products, a simulated log's truth sidecar and documents (:data:`DOCUMENT_SUFFIXES`: a README.md, a
PDF of the setup) are left alone quietly, as is what a DCA1000 writes beside its data
(``*_LogFile.txt``, ``*_LogFile.csv``).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

from autosar_cli.config import LOG_SUFFIXES, NMEA_SUFFIXES
from autosar_cli.store.outputs import input_problem, is_autosar_product

from .dca1000 import is_capture
from .sources import begins_as_a_container, container_of, is_log_directory

KINDS = ("log", "can", "nmea", "radar")
#: a DCA1000 capture's files: its data and the parameter files that state how it was recorded
CAPTURE_SUFFIXES = (".bin", ".mmwave.json", ".setup.json", ".cfg", ".lua")
#: documents a drive folder leaves alone quietly: the notes people keep beside a drive's logs, which no input's data
#: is (a .txt or .csv may be, a picture a camera's frame: those stay named in the warning)
DOCUMENT_SUFFIXES = (".md", ".rst", ".pdf", ".html", ".htm", ".doc", ".docx", ".odt")
_NMEA_SNIFF_BYTES = 65536
MAX_DEPTH = 4  #: folders inside a drive folder read for inputs (a CAN logger's LOG/<device>/<session>/)
_FILE_KINDS = {"can": "a CAN log file", "nmea": "an NMEA log file"}


class InputError(ValueError):
    """An input that is not there, or not what it is given as; the message names it."""


def classify_input(path: Path) -> str:
    """"log" (MCAP / bag / rosbag2), "can" (CAN log), "nmea" (NMEA text), "radar" (DCA1000 capture) or "drive" (a
    drive folder: :func:`drive_folder`)."""
    from .canlog import is_can_log

    if path.is_dir() and drive_folder(path) is not None:
        return "drive"
    if is_capture(path):
        return "radar"
    if begins_as_a_container(path):  # an MCAP or a bag saved as .log or .txt
        return "log"
    if path.is_file() and is_can_log(path):
        return "can"
    if path.suffix.lower() in NMEA_SUFFIXES or path.suffix.lower() == ".log":
        return "nmea"
    return "log"


def check_input(path: Path, kind: str) -> None:
    """Refuse, naming it, an input that is not there or not a file to read (a rosbag2 bag, a DCA1000 capture and a
    drive folder may be directories)."""
    problem = input_problem(path)
    if problem is not None:
        raise InputError(f"{path}: {problem}")
    if path.is_dir() and kind in _FILE_KINDS:
        raise InputError(f"{path}: a directory, not {_FILE_KINDS[kind]}")
    if kind in _FILE_KINDS and begins_as_a_container(path):
        what = {"mcap": "an MCAP log", "ros1": "a ROS 1 bag"}.get(container_of(path), "a log container")
        raise InputError(f"{path}: {what}, not {_FILE_KINDS[kind]}: give it as a LOG, without "
                         f"--{'can-log' if kind == 'can' else 'nmea'}")
    if kind == "radar" and path.is_file() and begins_as_a_container(path):  # read as a parameter file, it was
        what = {"mcap": "an MCAP log", "ros1": "a ROS 1 bag"}.get(container_of(path), "a log container")
        raise InputError(f"{path}: {what}, not a DCA1000 capture: give it as a LOG, without --radar (--radar "
                         "takes the capture's folder, its .bin or its parameter file)")
    if kind == "radar" and path.is_file():
        from .canlog import is_can_log

        if is_can_log(path):
            raise InputError(f"{path}: a CAN log file, not a DCA1000 capture: give it with --can-log")


#: files and folders a drive folder leaves out named in its warning (then counted)
SHOWN_LEFT_OUT = 10


@dataclass(frozen=True)
class DriveFolder:
    """What a drive folder holds: its inputs by kind (each in name order), and the entries it leaves alone."""

    path: Path
    inputs: dict[str, list[Path]]
    left_out: list[Path] = field(default_factory=list)

    def warning(self) -> str | None:
        """One line naming what the folder holds that no input is, or None."""
        if not self.left_out:
            return None
        shown = [str(p.relative_to(self.path)) + ("/" if p.is_dir() else "") for p in self.left_out[:SHOWN_LEFT_OUT]]
        more = len(self.left_out) - len(shown)
        names = ", ".join(shown) + (f" and {more} more" if more else "")
        dbc = " (a CAN database is given with --dbc)" if any(p.suffix.lower() == ".dbc" for p in self.left_out) else ""
        return f"{self.path}: not read, none of them a log, CAN log, NMEA capture or DCA1000 capture: {names}{dbc}"


def drive_folder(path: Path, depth: int = 0) -> DriveFolder | None:
    """The drive folder ``path`` is (module docstring), or None where it is a bag, a capture alone, a plain
    directory of storage files, or no directory. A folder inside it that holds inputs (a logger's ``can/``, down to
    :data:`MAX_DEPTH` folders deep) gives them too."""
    if not path.is_dir() or (path / "metadata.yaml").exists():
        return None
    from .canlog import is_can_log

    found: dict[str, list[Path]] = {kind: [] for kind in KINDS}
    capture_files, left_out = [], []
    try:
        entries = sorted(p for p in path.iterdir() if not p.name.startswith("."))
    except OSError:
        return None
    for entry in entries:
        name = entry.name.lower()
        if not (entry.is_dir() or entry.is_file()):  # a pipe, socket or device: opening one waits for ever
            left_out.append(entry)
        elif entry.is_dir():
            if is_capture(entry):
                found["radar"].append(entry)
            elif is_log_directory(entry):
                found["log"].append(entry)
            elif depth < MAX_DEPTH and (inner := drive_folder(entry, depth + 1)) is not None:
                for kind in KINDS:
                    found[kind] += inner.inputs[kind]
                left_out += inner.left_out
            elif not is_autosar_product(entry):
                left_out.append(entry)
        elif name.endswith(CAPTURE_SUFFIXES) or "_logfile." in name:
            capture_files.append(entry)
        elif begins_as_a_container(entry):
            found["log"].append(entry)
        elif is_can_log(entry):  # before the name: a logger's MDF4 renamed .bag is still its CAN log
            found["can"].append(entry)
        elif name.endswith(LOG_SUFFIXES):
            found["log"].append(entry)
        elif name.endswith((*NMEA_SUFFIXES, ".log")) and _holds_nmea(entry):
            found["nmea"].append(entry)
        elif not (name.endswith((".truth.h5", *DOCUMENT_SUFFIXES)) or is_autosar_product(entry)):
            left_out.append(entry)
    if capture_files and is_capture(path):
        found["radar"].insert(0, path)
    elif capture_files:
        left_out += capture_files
    kinds = [kind for kind in KINDS if found[kind]]
    # a ROS 1 bag, a bag's own folder or a log saved under another name is no storage file of a bag this folder is:
    # read as one, the folder left it unread without a word
    # so is an MCAP with its own truth sidecar beside it (autosar simulate's log, a bag's storage file has none): read
    # as a bag without metadata.yaml, it was warned of as a recording that did not finish and its truth went unfound
    not_storage = [p for p in found["log"] if not (p.is_file() and p.suffix.lower() in (".mcap", ".db3"))
                   or p.with_name(p.name + ".truth.h5").is_file()]
    # a capture's own folder inside it is no capture this folder is: it was read as no bag and no capture at all
    nested_capture = [p for p in found["radar"] if p != path]
    if not (found["can"] or found["nmea"] or len(kinds) > 1 or not_storage or nested_capture):
        return None  # a bag's storage files, or a capture's files, alone: read as that bag or capture
    return DriveFolder(path, {kind: found[kind] for kind in KINDS}, sorted(left_out))


def _holds_nmea(path: Path) -> bool:
    """Whether a text file holds an NMEA sentence (``$`` or ``!``, a talker and a type) in its first 64 KiB."""
    try:
        with path.open("rb") as f:
            head = f.read(_NMEA_SNIFF_BYTES)
    except OSError:
        return False
    return any(line.lstrip()[:1] in (b"$", b"!") and line.lstrip()[1:6].isalnum() for line in head.splitlines())


@dataclass
class SortedInputs:
    """An ingest's inputs by kind, drive folders opened, and what their folders left alone (one warning each)."""

    by_kind: dict[str, list[Path]]
    warnings: list[str] = field(default_factory=list)

    def all(self) -> list[tuple[Path, str]]:
        """(path, kind) of every input, kind by kind."""
        return [(p, kind) for kind in KINDS for p in self.by_kind[kind]]


def an_output_given_as_a_log(logs: Iterable[Path]) -> None:
    """Refuse a missing log named .h5 or .hdf5 as the output given without -o: ``autosar ingest LOG drive.h5`` (for an
    ingest that was given no -o; one given it, and run's or batch's directory, miss such a log as any input)."""
    for path in map(Path, logs):
        if path.suffix.lower() in (".h5", ".hdf5") and not path.exists() and not path.is_symlink():
            raise InputError(f"{path}: no such file or directory; an output is named with -o (`-o {path}`), "
                             "every name without it is an input")


def sort_inputs(logs: Iterable[Path], can_logs: Iterable[Path] = (), nmea_logs: Iterable[Path] = (),
                radar_captures: Iterable[Path] = ()) -> SortedInputs:
    """The inputs by kind: each of ``logs`` as what it is (:func:`classify_input`; a drive folder as what it holds),
    the others as given; each checked (:func:`check_input`)."""
    sorted_ = SortedInputs({"log": [], "can": [Path(p) for p in can_logs], "nmea": [Path(p) for p in nmea_logs],
                            "radar": [Path(p) for p in radar_captures]})
    for p in map(Path, logs):
        folder = drive_folder(p)  # a drive folder walked once: classify_input would walk it again
        if folder is None:
            sorted_.by_kind[classify_input(p)].append(p)
            continue
        for k in KINDS:
            sorted_.by_kind[k] += folder.inputs[k]
        if (said := folder.warning()) is not None:
            sorted_.warnings.append(said)
    seen: dict[tuple[int, int], Path] = {}
    for path, kind in sorted_.all():
        check_input(path, kind)
        st = path.stat()
        if (first := seen.setdefault((st.st_dev, st.st_ino), path)) is not path:
            same = "given twice" if first == path else f"the same file as {first}"
            raise InputError(f"{path}: {same}; give each input once (it would be read into the drive twice)")
    return sorted_


__all__ = ["CAPTURE_SUFFIXES", "DriveFolder", "InputError", "KINDS", "LOG_SUFFIXES", "NMEA_SUFFIXES", "SortedInputs",
           "an_output_given_as_a_log", "check_input", "classify_input", "drive_folder", "sort_inputs"]
