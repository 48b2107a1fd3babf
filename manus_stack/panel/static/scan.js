// Single-switch scanning: the page highlights its controls one after another, each for
// `stepMs`; one switch (a key: Space or Enter, as switch interfaces send) selects the
// highlighted control. On a pad button the switch works as the finger does: the arm moves
// while the switch is held. Scanning waits while the switch is down and goes on from the
// same control, so that the same choice is one press away again.

export const SWITCH_KEYS = new Set(["Space", "Enter", "NumpadEnter"]);

export class Scanner {
  /**
   * @param {HTMLElement} root  whose visible, enabled buttons are scanned (in page order)
   * @param {import("./hold.js").Hold} hold  the pad's hold-to-move
   * @param {number} stepMs  how long each control stays highlighted [ms]
   */
  constructor(root, hold, stepMs) {
    this.root = root;
    this.hold = hold;
    this.stepMs = stepMs;
    this.on = false;
    this.current = null;
    this.down = false;
    this.timer = null;
    // capture: the switch is the scanner's before any button sees it
    window.addEventListener("keydown", (e) => this._key(e, true), true);
    window.addEventListener("keyup", (e) => this._key(e, false), true);
  }

  /** The controls in scanning order: every visible, enabled button. */
  items() {
    return [...this.root.querySelectorAll("button")].filter(
      (b) => !b.disabled && b.offsetParent !== null,
    );
  }

  /** Scanning on or off. */
  set(on) {
    if (on === this.on) return;
    this.on = on;
    document.body.classList.toggle("scanning", on);
    this._highlight(null);
    clearInterval(this.timer);
    this.timer = null;
    if (on) {
      this.next();
      this._restart();
    }
  }

  /** Highlight the next control. */
  next() {
    const items = this.items();
    if (!items.length) return;
    const at = items.indexOf(this.current);
    this._highlight(items[(at + 1) % items.length]);
  }

  _restart() {
    clearInterval(this.timer);
    this.timer = setInterval(() => {
      if (!this.down) this.next();
    }, this.stepMs);
  }

  _highlight(el) {
    if (this.current) this.current.classList.remove("scan-focus");
    this.current = el;
    if (el) {
      el.classList.add("scan-focus");
      el.focus({ preventScroll: false });
      el.scrollIntoView({ block: "nearest" });
    }
  }

  _key(e, pressed) {
    if (!this.on || !SWITCH_KEYS.has(e.code)) return;
    e.preventDefault();
    e.stopPropagation();
    if (pressed && e.repeat) return;
    const el = this.current;
    if (pressed) {
      this.down = true;
      if (!el) return;
      if (el.dataset.axis) this.hold.start(el.dataset.axis, el);
      else el.click();
      return;
    }
    this.down = false;
    if (el && el.dataset.axis) this.hold.stop();
    if (!el || !el.isConnected || el.offsetParent === null) this._highlight(null);
    this._restart(); // a full step on the same control after the press
  }
}
