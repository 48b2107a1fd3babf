() => {
  // The colours the browser rendered: every visible text with the colour behind it, every
  // visible button's edge (its border, or its fill when it has none) with the colour
  // behind the button, and the focus ring of the highlighted control.
  const rgba = (css) => {
    const v = css.match(/[\d.]+/g).map(Number);
    return v.length === 3 ? [...v, 1] : v;
  };
  const behind = (el) => {
    for (let e = el; e; e = e.parentElement) {
      const c = rgba(getComputedStyle(e).backgroundColor);
      if (c[3] > 0) return c;
    }
    return [255, 255, 255, 1];
  };
  const visible = (el) => el.getClientRects().length > 0 && getComputedStyle(el).visibility !== "hidden";
  const texts = [];
  for (const el of document.querySelectorAll("body *")) {
    if (!visible(el)) continue;
    const own = [...el.childNodes].filter((n) => n.nodeType === 3 && n.textContent.trim());
    if (!own.length) continue;
    const style = getComputedStyle(el);
    texts.push({
      what: own.map((n) => n.textContent.trim()).join(" ").slice(0, 40),
      fg: rgba(style.color),
      bg: behind(el),
      size: parseFloat(style.fontSize),
      weight: Number(style.fontWeight),
    });
  }
  const edges = [];
  for (const b of document.querySelectorAll("button")) {
    if (!visible(b)) continue;
    const style = getComputedStyle(b);
    const border = rgba(style.borderTopColor);
    const edge = parseFloat(style.borderTopWidth) > 0 && border[3] > 0 ? border : rgba(style.backgroundColor);
    edges.push({ id: b.id, edge, bg: behind(b.parentElement) });
    if (b.classList.contains("scan-focus")) {
      edges.push({ id: `${b.id} (ring)`, edge: rgba(style.outlineColor), bg: behind(b.parentElement) });
    }
  }
  return { texts, edges };
}
