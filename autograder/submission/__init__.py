"""A student's hand-in read: its files found (``layout``) and each homework function's code
(``read``).
"""
