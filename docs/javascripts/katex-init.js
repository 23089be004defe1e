// Render the math that pymdownx.arithmatex (generic mode) leaves as \( \) and \[ \] with the vendored KaTeX,
// on the first load and after every instant-navigation page change (Material's document$ observable).
document$.subscribe(({ body }) => {
  renderMathInElement(body, {
    delimiters: [
      { left: "\\[", right: "\\]", display: true },
      { left: "\\(", right: "\\)", display: false },
    ],
    throwOnError: false,
  });
});
