"""nbgrader: the course built for it, the grading after its autograde step, the pictures in its
feedback.
"""
