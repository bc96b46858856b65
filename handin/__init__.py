"""What a student runs to hand in: the PDF for Gradescope and the code zip for the autograder.

  handin.pdf               notebooks -> one Gradescope-ready PDF (python -m handin pdf)
  handin.code_zip          notebooks -> the code zip, and what each notebook defines (python -m handin zip)
  handin.cover             the PDF's cover: name, questions answered
  handin.html              nbconvert preprocessors and exporter (printable HTML)
  handin.browser           finding and driving a headless Chromium
  handin.mathjax           a local MathJax for offline math
  handin.hand_in_notebook  the hand-in notebook (notebooks/hand_in.ipynb) that runs the above in Colab

Layer 4: imports ``core`` and ``starter`` (its notebook reader).
"""
