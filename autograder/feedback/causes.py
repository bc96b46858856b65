"""One likely mistake per cause: how a check's feedback names a catalogue mistake, and how a reader
is told it once.

A check whose judging recognised a mistake of the catalogue (``judging.mistakes``) ends its feedback
with the line ``Likely mistake: <name>. <hint>`` (``autograder.feedback.words.mistake_note``).
Several checks of a question often recognise the same mistake (one findM2 bug fails the camera, C2
and w): each of them still names it, since each costs points, but only the first a reader meets
gives the hint; the later ones say ``Likely mistake: <name> (the same cause as above)``.
:func:`said_once` is that rule, for every writer of feedback (feedback.md, results.json, the
feedback page).  The class report counts recorded codes (``TestResult.mistakes``), a student once
per question and mistake, never these words.
"""

from __future__ import annotations

__all__ = ["LIKELY", "said_once"]

LIKELY = "Likely mistake: "


def said_once(text: str, qid: str, said: dict | None, rank: int = 0) -> str:
    """``text``, a check's feedback under question ``qid``, with each "Likely mistake: <name>. <hint>"
    line said in full only when no check read before gave it.

    said : name -> (question, rank) of the mistakes named by the checks read before, updated here;
        None: ``text`` unchanged.  Its scope is the caller's: one question's checks, or a whole page
        (a later question then says "(the same cause as above, under Q3.3)").
    rank : when the reader sees this check (0: at once; higher: later, e.g. after the due date).
        A check refers back only to one seen no later than itself: a hint given only in a check
        shown after the grades are published is given again in a check shown at once.
    """
    if said is None or LIKELY not in text:
        return text
    out = []
    for line in text.split("\n"):
        if line.startswith(LIKELY):
            body = line.rstrip()
            name = body[len(LIKELY):].split(". ", 1)[0].rstrip(".")
            before = said.get(name)
            if before is not None and before[1] <= rank:
                where = "" if before[0] == qid else f", under {before[0]}"
                # the line's trailing spaces are Markdown's line break: kept
                line = f"{LIKELY}{name} (the same cause as above{where}){line[len(body):]}"
            if before is None or rank < before[1]:
                said[name] = (qid, rank)
        out.append(line)
    return "\n".join(out)
