"""Where a class is graded: the batch (and its output folder, gradebook and regrade), Gradescope,
nbgrader and a cluster; each grades through ``autograder.grading.run``.
"""
