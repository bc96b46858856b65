"""What a public check returns and prints: one line per item, known mistakes named.

A check calls the student's function through :func:`call`, which turns the ways a stub or a
crash can end into a status instead of a traceback, and collects :class:`CheckItem` lines into
a :class:`CheckReport`.  A check prints its report as plain text (aligned, and it survives a
PDF export); a report displayed later in a notebook shows as an HTML table, and one returned
by the cell that printed it is not shown a second time.
"""

from __future__ import annotations

import html
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from judging.hints import numpy2_hint
from judging.mistakes import Mistake
from judging.verdict import Verdict, figure_text, same_error

__all__ = ["DISCLAIMER", "NOT_IMPLEMENTED", "CheckItem", "CheckReport", "Outcome", "call", "student_frame"]

NOT_IMPLEMENTED = "not implemented yet"
DISCLAIMER = "These are public checks: passing them promises nothing about the hidden tests."
_TICK, _CROSS, _SKIP = "\u2713", "\u2717", "-"


@dataclass(frozen=True)
class CheckItem:
    """One line of a report.

    name : what was checked, e.g. "rank 2 (noisy matches)".
    passed : True, False, or None for an item that was not run (skipped, with ``value`` saying why).
    value : the figure of merit measured ("s3/s2 = 2e-16"), or the error message.
    goal : what it is compared with ("< 1e-6"), "" when the item has no figure.
    mistakes : known mistakes recognised when the item failed.
    because : the part that failed, when ``value`` may meet ``goal`` (a Verdict's ``because``).
    """

    name: str
    passed: bool | None
    value: str = ""
    goal: str = ""
    mistakes: tuple[Mistake, ...] = ()
    because: str = ""

    @property
    def figure(self) -> str:
        """The value and goal as shown, "failed" in words when the item failed (the cross alone is
        easy to miss beside a figure that looks like it meets its goal)."""
        if self.value == NOT_IMPLEMENTED:
            return self.value
        return figure_text(self.passed is not False, self.value, "", self.because)

    def lines(self) -> list[str]:
        mark = _SKIP if self.passed is None else (_TICK if self.passed else _CROSS)
        text = f"  {mark} {self.name}"
        figure = self.figure + (f"   (goal {self.goal})" if self.goal else "")
        if figure:
            text = f"{text:<58} {figure}"
        out = [text]
        for m in self.mistakes:
            out.append(f"      known mistake: {m.name}. {m.hint}")
            if m.evidence:
                out.append(f"        ({m.evidence})")
        return out


@dataclass
class CheckReport:
    """The result of one check.

    title : the function checked, e.g. "eightpoint".
    items : the CheckItem lines, in order.
    notes : lines printed before the disclaimer (e.g. "default data not found, skipped").
    passed : every item that ran passed, at least one ran, and the function is implemented.
    """

    title: str
    items: list[CheckItem] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    # The notebook cell that printed the report, so that displaying the returned report in the
    # same cell does not show it twice.
    printed_in: int | None = field(default=None, repr=False, compare=False)

    @property
    def passed(self) -> bool:
        ran = [i for i in self.items if i.passed is not None]
        return bool(ran) and all(i.passed for i in ran)

    @property
    def not_implemented(self) -> bool:
        return any(i.value == NOT_IMPLEMENTED for i in self.items)

    @property
    def mistakes(self) -> list[Mistake]:
        """Every known mistake recognised, each once, in the order found."""
        seen: dict[str, Mistake] = {}
        for item in self.items:
            for m in item.mistakes:
                seen.setdefault(m.code, m)
        return list(seen.values())

    def add(self, name: str, passed: bool | None, value: str = "", goal: str = "",
            mistakes=(), because: str = "") -> bool | None:
        self.items.append(CheckItem(name, None if passed is None else bool(passed), value, goal,
                                    tuple(m for m in mistakes if m is not None), because))
        return passed

    def judged(self, verdict: Verdict, where: str = "") -> bool:
        """Add the item of one judgment (judging/), ``where`` naming the data in brackets."""
        name = f"{verdict.what} ({where})" if where else verdict.what
        measured = "; ".join([verdict.measured, *verdict.lines]) if verdict.lines else verdict.measured
        self.add(name, verdict.passed, measured, verdict.goal, verdict.mistakes, verdict.because)
        return verdict.passed

    def text(self) -> str:
        n_ran = sum(i.passed is not None for i in self.items)
        n_ok = sum(bool(i.passed) for i in self.items)
        if self.not_implemented:
            head = f"check {self.title}: {NOT_IMPLEMENTED}"
        else:
            head = f"check {self.title}: {n_ok}/{n_ran} passed" + ("" if self.passed else "  <- see the crosses")
        lines = [head]
        for item in _merged(self.items):
            lines.extend(item.lines())
        lines.extend(f"  note: {n}" for n in self.notes)
        lines.append(DISCLAIMER)
        return "\n".join(lines)

    __str__ = text

    def __repr__(self) -> str:
        state = NOT_IMPLEMENTED if self.not_implemented else ("passed" if self.passed else "failed")
        return f"CheckReport({self.title}: {state}, {len(self.items)} items)"

    def show(self) -> None:
        """Print the report and remember the notebook cell (if any) it was printed in."""
        print(self.text())
        self.printed_in = _cell_number()

    def _ipython_display_(self) -> None:
        if self.printed_in is not None and self.printed_in == _cell_number():
            return  # ``check_x(f)`` as a cell's last line: already printed just above
        from IPython.display import display

        display({"text/plain": self.text(), "text/html": self._repr_html_()}, raw=True)

    def _repr_html_(self) -> str:
        rows = []
        for item in self.items:
            mark, colour = ((_SKIP, "#888") if item.passed is None
                            else (_TICK, "#1a7f37") if item.passed else (_CROSS, "#cf222e"))
            hint = "".join(f"<br><b>known mistake: {html.escape(m.name)}.</b> {html.escape(m.hint)}"
                           + (f" <i>({html.escape(m.evidence)})</i>" if m.evidence else "")
                           for m in item.mistakes)
            rows.append(f"<tr><td style='color:{colour};font-weight:bold'>{mark}</td>"
                        f"<td style='text-align:left'>{html.escape(item.name)}{hint}</td>"
                        f"<td style='text-align:left'>{html.escape(item.figure)}</td>"
                        f"<td style='text-align:left'>{html.escape(item.goal)}</td></tr>")
        notes = "".join(f"<div>note: {html.escape(n)}</div>" for n in self.notes)
        head = html.escape(self.text().splitlines()[0])
        return (f"<div><b>{head}</b><table><tr><th></th><th>check</th><th>measured</th><th>goal</th></tr>"
                f"{''.join(rows)}</table>{notes}<div><i>{html.escape(DISCLAIMER)}</i></div></div>")


_RUNS_ON = "runs on "


def _merged(items: list[CheckItem]) -> list[CheckItem]:
    """The items, failed calls that raised the same error ("runs on X" items with the same message)
    said once with a count: a function failing on every input fails the same way on each."""
    groups: dict[str, list[CheckItem]] = {}
    for item in items:
        if item.passed is False and item.name.startswith(_RUNS_ON) and item.value:
            groups.setdefault(item.value, []).append(item)
    out, done = [], set()
    for item in items:
        group = groups.get(item.value) if item.passed is False and item.name.startswith(_RUNS_ON) else None
        if not group or len(group) == 1:
            out.append(item)
        elif item.value not in done:
            done.add(item.value)
            wheres = [i.name[len(_RUNS_ON):] for i in group]
            name = _RUNS_ON + (", ".join(wheres[:-1]) + f" and {wheres[-1]}" if len(wheres) <= 3 else f"{len(wheres)} inputs")
            out.append(CheckItem(name, False, f"{item.value} {same_error(len(group))}", item.goal, item.mistakes))
    return out


def _cell_number() -> int | None:
    """The execution count of the running notebook cell, or None outside IPython."""
    try:
        from IPython import get_ipython
    except ImportError:
        return None
    shell = get_ipython()
    return None if shell is None else getattr(shell, "execution_count", None)


@dataclass(frozen=True)
class Outcome:
    """How a call of the student's function ended.

    status : "ok", "not implemented" (NotImplementedError raised, or None returned) or "error".
    value : what it returned (status "ok").
    message : one line "ExceptionType: message" (status "error").
    """

    status: str
    value: Any = None
    message: str = ""

    @property
    def ok(self) -> bool:
        return self.status == "ok"


def _is_empty(value) -> bool:
    # A stub that returns None, or a tuple of Nones (``return None, None``), is not written yet.
    if value is None:
        return True
    return isinstance(value, (tuple, list)) and len(value) > 0 and all(v is None for v in value)


def call(fn: Callable, *args, **kwargs) -> Outcome:
    """Run the student's ``fn(*args, **kwargs)`` and report how it ended, never raising.

    An exception becomes one line "ExceptionType: message (in <function>, <cell or file>, line L)",
    the place being the innermost frame of the traceback that lies in the student's code (not in
    numpy, scipy, the standard library or the kit's own packages).
    """
    if not callable(fn):
        return Outcome("error", message=f"expected a function, got {type(fn).__name__}")
    try:
        try:
            value = fn(*args, **kwargs)
        except FileNotFoundError as exc:
            # Code that saves into result/ or results/ (as the handouts said) where that folder is
            # missing: made, as the grader's sandbox has it, and the call made again.
            if not _made_result_folder(exc):
                raise
            value = fn(*args, **kwargs)
    except NotImplementedError:
        return Outcome("not implemented")
    except Exception as exc:  # noqa: BLE001 - any failure of student code is reported as one line
        hint = numpy2_hint(str(exc))  # a name NumPy removed: say which and what replaces it
        text = " ".join((str(exc).splitlines() or [""])[0].split() if hint else str(exc).split())
        if len(text) > 200:
            text = text[:197] + "..."
        line = f"{type(exc).__name__}: {text}" if text else type(exc).__name__
        where = student_frame(exc.__traceback__)
        message = f"{line} (in {where})" if where else line
        return Outcome("error", message=f"{message.rstrip('.')}. {hint}" if hint else message)
    if _is_empty(value):
        return Outcome("not implemented")
    return Outcome("ok", value)


def _made_result_folder(exc: FileNotFoundError) -> bool:
    """True after making the missing folder of a relative path under one of the handouts' result
    folders (``core.paths.RESULT_FOLDERS``) that ``exc`` names; False for any other missing file."""
    import os

    from core.paths import RESULT_FOLDERS

    name = exc.filename if isinstance(exc.filename, str) else None
    if not name or os.path.isabs(name):
        return False
    folder = os.path.dirname(os.path.normpath(name))
    if not folder or os.path.basename(folder) not in RESULT_FOLDERS or os.path.isdir(folder):
        return False
    try:
        os.makedirs(folder, exist_ok=True)
    except OSError:
        return False
    return True


# Code that is not the student's: the interpreter's own library and installed packages, and the
# kit's packages (a frame there is a helper the student called, not the line to look at).
_KIT_PACKAGES = ("core", "scenes", "starter", "judging", "handin", "kit", "autograder", "solutions")


def _library_roots() -> tuple[str, ...]:
    import os
    import sys
    import sysconfig

    roots = {sys.prefix, sys.base_prefix, sys.exec_prefix, *(sysconfig.get_paths().get(k, "") for k in
                                                             ("stdlib", "platstdlib", "purelib", "platlib"))}
    kit = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    roots |= {os.path.join(kit, p) + os.sep for p in _KIT_PACKAGES}
    return tuple(sorted(r for r in roots if r))


def _is_student_file(filename: str) -> bool:
    import os

    if filename.startswith("<frozen") or filename in ("<string>", "<stdin>"):
        return False
    if filename.startswith("<"):
        return True  # exec'd cells, from_notebook's "<name>.ipynb, cell k"
    path = os.path.abspath(filename)
    return not any(path == r.rstrip(os.sep) or path.startswith(r if r.endswith(os.sep) else r + os.sep)
                   for r in _library_roots())


def _cell_label(filename: str) -> str:
    """'cell In[5]' for a notebook cell run in IPython, the file's name otherwise."""
    import os

    try:
        from IPython import get_ipython

        shell = get_ipython()
        number = None if shell is None else getattr(shell.compile, "_filename_map", {}).get(filename)
    except Exception:  # noqa: BLE001 - no IPython, or another one: fall back to the file's name
        number = None
    if number is not None:
        return f"cell In[{number}]"
    if filename.startswith("<") or ".ipynb, cell" in filename:
        return filename.strip("<>")
    return os.path.basename(filename)


def student_frame(tb) -> str:
    """'<function>, <cell or file>, line L' of the innermost traceback frame in student code, or ''."""
    found, function = None, None
    while tb is not None:
        code = tb.tb_frame.f_code
        if _is_student_file(code.co_filename):
            found = (code.co_filename, tb.tb_lineno)
            # A comprehension or lambda is named after the function around it.
            if not code.co_name.startswith("<") or function is None:
                function = code.co_name
        tb = tb.tb_next
    if found is None:
        return ""
    (filename, line), name = found, function
    return f"{name}, {_cell_label(filename)}, line {line}"
