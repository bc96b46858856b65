"""Gradescope: the autograder bundle built for it, the grading inside its container, the pictures
added to its results.json.
"""
