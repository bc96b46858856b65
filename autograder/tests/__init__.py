"""Judges of the hidden checks not yet rewritten on ``judging/``: one module per solutions module.

Each has ``prepare(scenes)`` (the hidden inputs and the reference's results on them),
``calls(prepared, time_scale)`` (the student calls to make) and ``judge(prepared, outcomes)``
(the question's results).  They run from the pytest tests of ``autograder/hidden/`` through
``autograder.hidden.legacy``; a module is deleted once its test calls ``judging`` instead.
"""
