// Offline MathJax 2 set-up for printing. Only the STIX-Web web fonts are used: they are the ones
// every MathJax copy we load from (Debian's libjs-mathjax, the jupyter-server-mathjax wheel) ships,
// and they map glyphs to Unicode, so the printed math stays searchable text in the PDF.
MathJax.Hub.Config({
  tex2jax: {
    inlineMath: [["$", "$"], ["\\(", "\\)"]],
    displayMath: [["$$", "$$"], ["\\[", "\\]"]],
    processEscapes: true,
    processEnvironments: true
  },
  TeX: { equationNumbers: { autoNumber: "AMS", useLabelIds: true } },
  "HTML-CSS": {
    availableFonts: [],
    preferredFont: null,
    webFont: "STIX-Web",
    imageFont: null,
    linebreaks: { automatic: false },
    EqnChunk: 500,
    EqnChunkDelay: 0
  },
  MMLorHTML: { prefer: "HTML" },
  messageStyle: "none",
  showMathMenu: false,
  showProcessingMessages: false
});
// The printer waits for this attribute (Playwright) or runs out of virtual time (plain chromium).
MathJax.Hub.Register.StartupHook("End", function () {
  document.documentElement.setAttribute("data-hw4-math", "done");
});
