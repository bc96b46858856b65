"""Grading: a run set up once (configuration, inputs, sandboxes, workers, canary), one submission's
pytest session in a worker, its time budget, and the answer key as a submission.
"""
