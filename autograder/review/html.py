"""Offline HTML pages of the review: the look-alike pairs side by side.  No script, no external file.

Names, origins and code are the students': every one passes ``core.untrusted.for_html``.
"""

from __future__ import annotations

from core.untrusted import for_html

from .similarity import FLAG, FunctionComparison, Group

__all__ = ["similarity_page", "STYLE"]

STYLE = """
body{font-family:system-ui,sans-serif;margin:1.5em;max-width:1400px}
table{border-collapse:collapse;margin:.5em 0}td,th{border:1px solid #ccc;padding:2px 8px;text-align:left}
th{background:#f3f3f3}.flag{background:#fff3cd}
.side{display:flex;gap:1em}.side>div{flex:1;min-width:0}
pre{background:#fafafa;border:1px solid #ddd;padding:4px;overflow-x:auto;font-size:12px;margin:0}
.ln{color:#999;user-select:none}.hit{background:#ffe08a}
details{margin:.6em 0}summary{cursor:pointer}
"""


def _code(source: str, hits: set[int]) -> str:
    rows = []
    for k, line in enumerate(source.split("\n"), start=1):
        text = f'<span class="ln">{k:4d} </span>{for_html(line)}'
        rows.append(f'<span class="hit">{text}</span>' if k in hits else text)
    return "<pre>" + "\n".join(rows) + "</pre>"


def similarity_page(comparisons: dict[str, FunctionComparison], sources: dict, *, top: int = 10,
                    groups: list[Group] = ()) -> str:
    """The page: the groups first, then per function the ranked pairs (flagged ones and at least
    ``top``), each with both sources side by side and the lines carrying common fingerprints
    highlighted.

    sources: (submission name, function) -> FunctionSource; groups: ``similarity.groups(comparisons)``.
    """
    parts = ["<!DOCTYPE html><html><head><meta charset='utf-8'><title>Look-alike code</title>",
             f"<style>{STYLE}</style></head><body><h1>Look-alike code: pairs to look at</h1>",
             "<p>For each function, the pairs of submissions whose code is most alike once variable names, "
             "statement order, comments and formatting are set aside, with the handout's code left out. "
             f"Pairs scoring {FLAG:g} or more are marked <span class='flag'>look at these</span>. "
             "A high score is a reason to read the two side by side, not a finding: short functions, "
             "shared sources and common textbook code can look alike. The course staff decide.</p>",
             "<h2 id='groups'>Groups</h2>"]
    if groups:
        parts.append("<p>Submissions linked by flagged pairs, in any function: read each group together.</p>"
                     "<table><tr><th>submissions</th><th>who</th><th>flagged in (highest score)</th></tr>")
        for g in groups:
            where = ", ".join(f"<a href='#{for_html(f)}'>{for_html(f)}</a> {s:.2f}" for f, s in g.functions.items())
            parts.append(f"<tr class='flag'><td>{len(g.members)}</td><td>{for_html(', '.join(g.members))}</td>"
                         f"<td>{where}</td></tr>")
        parts.append("</table>")
    else:
        parts.append("<p>No pair scored high enough to look at.</p>")
    for function, comp in comparisons.items():
        pairs = comp.ranked(top, flagged_too=False)
        flagged = int(((comp.score >= FLAG).sum()) // 2) if len(comp.names) else 0
        parts.append(f"<h2 id='{function}'>{for_html(function)}</h2><p>{len(comp.names)} submissions compared, "
                     f"{flagged} pair(s) to look at"
                     + (f"; without their own code for it: {for_html(', '.join(comp.skipped))}" if comp.skipped
                        else "") + (f"; the first {len(pairs)} shown here, the groups above and similarity.csv link every one"
                                    if flagged > len(pairs) else "") + ".</p>")
        if not pairs:
            continue
        parts.append("<table><tr><th>rank</th><th>a</th><th>b</th><th>score</th><th>jaccard</th>"
                     "<th>containment</th><th>shared</th><th></th></tr>")
        for p in pairs:
            cls = " class='flag'" if p.flagged else ""
            parts.append(f"<tr{cls}><td>{p.rank}</td><td>{for_html(p.a)}</td><td>{for_html(p.b)}</td>"
                         f"<td>{p.score:.2f}</td><td>{p.jaccard:.2f}</td><td>{p.containment:.2f}</td>"
                         f"<td>{p.shared:.1f}</td><td><a href='#{function}-{p.rank}'>side by side</a></td></tr>")
        parts.append("</table>")
        for p in pairs:
            la, lb = comp.matching_lines(p.a, p.b)
            sa, sb = sources[(p.a, function)], sources[(p.b, function)]
            tag = " (look at these)" if p.flagged else ""
            parts.append(f"<details id='{function}-{p.rank}'{' open' if p.flagged else ''}><summary>#{p.rank} "
                         f"{for_html(p.a)} and {for_html(p.b)}: score {p.score:.2f}{tag}</summary>"
                         "<div class='side'>"
                         f"<div><b>{for_html(p.a)}</b> <small>{for_html(sa.origin)}</small>{_code(sa.source, la)}</div>"
                         f"<div><b>{for_html(p.b)}</b> <small>{for_html(sb.origin)}</small>{_code(sb.source, lb)}</div>"
                         "</div></details>")
    parts.append("</body></html>")
    return "\n".join(parts)
