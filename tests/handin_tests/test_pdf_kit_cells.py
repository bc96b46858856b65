"""The PDF holds the student's work: the kit's own cells print no folder of the student's
machine and no traceback (``handin.html.KitOutputsPreprocessor``); a student's own cell keeps
what it printed."""

from __future__ import annotations

import nbformat
from nbformat.v4 import new_code_cell, new_output

from handin import html as pdf_html
from kit import notebooks as nbk

TRACEBACK = ["\x1b[0;31mValueError\x1b[0m                                Traceback (most recent call last)",
             "File /Users/ana/hw4/starter/keypoints.py:120, in plot_3d_keypoint(P)"]


def _error(evalue: str):
    return new_output("error", ename="ValueError", evalue=evalue, traceback=TRACEBACK)


def test_a_kit_cell_prints_no_path_and_no_traceback():
    setup = new_code_cell(pdf_html.SETUP_FIRST_LINE + "\nimport sys", metadata={"tags": [pdf_html.PLUMBING_TAG]},
                          outputs=[new_output("stream", name="stdout", text="homework kit: /Users/ana/Desktop/hw4-kit\n"
                                                                               "your notebooks are read from: "
                                                                               "/content/drive/MyDrive/hw4\n")])
    figure = new_code_cell('with kit_cell("Q6"):\n    display(plot_3d_keypoint(P))',
                           metadata={"tags": ["figure", pdf_html.KIT_CELL_TAG]},
                           outputs=[_error("P: expected at least 12 keypoint rows, got 8 (/home/ana/hw4/x.py)")])
    pre = pdf_html.KitOutputsPreprocessor()
    text = pre.preprocess_cell(setup, {}, 0)[0].outputs[0].text
    assert "homework kit: found" in text and "/Users" not in text and "/content/drive" not in text
    out, = pre.preprocess_cell(figure, {}, 1)[0].outputs
    assert out.output_type == "stream" and "Traceback" not in out.text and "/home/ana" not in out.text
    assert out.text.startswith("this cell of the kit stopped: ValueError: P: expected at least 12 keypoint rows")


def test_a_students_cell_keeps_its_output():
    mine = new_code_cell("print(my_path)", outputs=[new_output("stream", name="stdout", text="/home/ana/notes\n"),
                                                    _error("mine")])
    out = pdf_html.KitOutputsPreprocessor().preprocess_cell(mine, {}, 0)[0]
    assert out.outputs[0].text == "/home/ana/notes\n" and out.outputs[1].output_type == "error"


def test_the_builder_tags_every_cell_the_kit_writes():
    nb = nbk.build_notebook("q6_multiview_car", "student")
    for cell in nb.cells:
        if cell.cell_type != "code":
            continue
        ours = cell.source.startswith("def ")   # the student's stubs
        tagged = pdf_html._is_kit_cell(cell)
        assert tagged != ours, cell.source[:80]
    assert isinstance(nb, nbformat.NotebookNode)
