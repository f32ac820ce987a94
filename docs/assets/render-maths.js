// Typesets the maths of every page with the bundled KaTeX (no network needed).
// The build marks each formula as \( ... \) or \[ ... \] inside an element of class
// "arithmatex": pymdownx.arithmatex on the Markdown pages and in docstrings,
// docs/hooks.py in the notebooks' Markdown cells and their tables of contents.
// Only those delimiters are read, so a formula the build missed stays visible as
// raw $...$ (tests/test_docs.py fails on it) instead of being half-guessed here.
function renderMaths(root) {
  for (const element of root.querySelectorAll(".arithmatex")) {
    renderMathInElement(element, {
      delimiters: [
        { left: "\\(", right: "\\)", display: false },
        { left: "\\[", right: "\\]", display: true },
      ],
      throwOnError: false,
    });
  }
}

if (typeof document$ !== "undefined") {
  // Material's instant navigation swaps the page without a reload: typeset each new one.
  document$.subscribe(({ body }) => renderMaths(body));
} else {
  document.addEventListener("DOMContentLoaded", () => renderMaths(document.body));
}
