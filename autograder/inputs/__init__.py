"""What the grader grades on: its configuration, the hidden scenes drawn from the secret, each
check's prepared cases, and the keep that remembers what was made once.
"""
