// Hold-to-move: while a pad button is held, the page itself sends its command every
// `repeatMs` (50 ms: three per jog deadman of 150 ms) and the server publishes each one at
// once. Letting go (finger lifted, pointer cancelled, key released, focus lost, the page
// hidden or left) sends one release at once. If the page freezes or the network goes
// silent, the commands stop coming and the controller's own deadman stops the arm; a
// socket that closes makes the server send the stop itself.

export class Hold {
  /**
   * @param {(msg: object) => boolean} send  sends one message; false when not connected
   * @param {number} repeatMs  how often a held button's command is repeated [ms]
   */
  constructor(send, repeatMs) {
    this.send = send;
    this.repeatMs = repeatMs;
    this.axis = null;
    this.el = null;
    this.timer = null;
    window.addEventListener("blur", () => this.stop());
    window.addEventListener("pagehide", () => this.stop());
    document.addEventListener("visibilitychange", () => {
      if (document.visibilityState !== "visible") this.stop();
    });
  }

  /** Start moving along `axis` (the pad button `el` is held). */
  start(axis, el) {
    if (this.axis === axis) return;
    this.stop();
    this.axis = axis;
    this.el = el;
    el.classList.add("held");
    el.setAttribute("aria-pressed", "true");
    // `at`: when, on this page's monotonic clock; the server drops a command that
    // reaches it late (it sat in a buffer), so a backlog never moves the arm
    const tick = () => {
      if (!this.send({ t: "jog", axis, at: performance.now() })) this.cancel();
    };
    tick();
    this.timer = setInterval(tick, this.repeatMs);
  }

  /** The button was let go: stop now. */
  stop() {
    if (this.axis === null) return;
    this._clear();
    this.send({ t: "release" });
  }

  /** The connection is gone: stop sending (the server and the deadman stop the arm). */
  cancel() {
    if (this.axis !== null) this._clear();
  }

  _clear() {
    clearInterval(this.timer);
    this.timer = null;
    this.el.classList.remove("held");
    this.el.setAttribute("aria-pressed", "false");
    this.axis = null;
    this.el = null;
  }

  /** Make `el` a hold-to-move button for `axis`: touch, mouse and keyboard. */
  attach(el, axis) {
    el.setAttribute("aria-pressed", "false");
    el.addEventListener("pointerdown", (e) => {
      if (e.button !== 0) return;
      e.preventDefault();
      el.setPointerCapture(e.pointerId);
      this.start(axis, el);
    });
    for (const type of ["pointerup", "pointercancel", "lostpointercapture"]) {
      el.addEventListener(type, () => {
        if (this.el === el) this.stop();
      });
    }
    el.addEventListener("keydown", (e) => {
      if (e.key !== " " && e.key !== "Enter") return;
      e.preventDefault();
      if (!e.repeat) this.start(axis, el);
    });
    el.addEventListener("keyup", (e) => {
      if (e.key !== " " && e.key !== "Enter") return;
      e.preventDefault();
      if (this.el === el) this.stop();
    });
    el.addEventListener("blur", () => {
      if (this.el === el) this.stop();
    });
    el.addEventListener("contextmenu", (e) => e.preventDefault());
  }
}
