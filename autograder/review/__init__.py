"""What course staff look at after a batch is graded: look-alike code and the class report.

``python -m autograder.review similar SUBMISSIONS... --out DIR`` ranks, for every function of the
homework, the pairs of submissions whose code looks alike once names, statement order, comments
and formatting are set aside (``similarity``), and writes a side-by-side HTML page of the pairs to
look at.  ``python -m autograder.review report GRADED_DIR --out DIR`` summarises a graded folder:
who passed what, the named mistakes, score histograms, grades.csv and a Canvas import file
(``report``).  Both read only files; neither runs student code.

This package imports only ``core``, the standard library, numpy and (for the histograms)
matplotlib; the command line also reads the grader config (``autograder.inputs.config``) for the
library calls the report lists (``library_calls``: uses of OpenCV, SciPy's Rotation, skimage's
ransac... that do what the homework asks, for the staff to look at).
"""
