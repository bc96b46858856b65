"""What a student and the staff read of a grading: the results model, the feedback's words, the
likely causes of a failure, the pictures of the public data and the offline feedback page.
"""
