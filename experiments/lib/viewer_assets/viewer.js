/* Interactive HDR image comparison viewer of the experiment report.
 *
 * Each comparison is an element with a `data-viewer` attribute holding a JSON
 * manifest (<script type="application/json" class="vrv-manifest">) written by
 * experiments/lib/viewer.py. Pixel data (linear float32 RGB, error maps) comes
 * in <script> files `viewer-data/<id>.js` that call VRViewer.blob(id, base64)
 * (zlib-compressed float32 images, float16 error maps):
 * a page opened from file:// cannot read image pixels (Chromium taints a canvas
 * that draws a file:// image) nor fetch files, but it can run scripts. Data of
 * viewers below the fold is loaded when they come near the viewport.
 *
 * Keys act on the viewer under the mouse, else on the last one clicked:
 *   1-9 pick an image, Space flips between the last two picked,
 *   + / - exposure up / down one stop, e toggles the error map,
 *   m switches its metric (relMSE per pixel / FLIP), g side by side,
 *   r resets zoom and exposure. Wheel zooms around the cursor, drag pans;
 *   the view is shared by every image of a comparison.
 *
 * State for tests and scripts is mirrored in data attributes of the element:
 * data-state (idle|loading|ready|failed), data-selected, data-mode
 * (image|error), data-metric, data-exposure (stops), data-zoom (screen px per
 * image px), data-drawn (what the canvases show) and data-readout (JSON of
 * the pixel under the cursor: x, y, image, rgb, and error in error mode).
 */
(function () {
  "use strict";

  // Matplotlib's magma at 17 evenly spaced points (FLIP's own colour map).
  var MAGMA = [0, 0, 4, 10, 8, 34, 29, 17, 71, 54, 16, 107, 81, 18, 124, 106, 28, 129,
    131, 38, 129, 156, 46, 127, 183, 55, 121, 208, 65, 111, 231, 82, 99, 245, 107, 92,
    252, 137, 97, 254, 167, 114, 254, 196, 136, 253, 226, 163, 252, 253, 191];
  var METRICS = {relmse: "relMSE", flip: "FLIP"};
  var HELP = "1-9 pick · Space flip last two · wheel zoom · drag pan · +/- exposure · " +
    "e error map · m relMSE/FLIP · g side by side · r reset";
  var MIN_ZOOM_OF_FIT = 0.25, MAX_ZOOM = 512, BACKGROUND = "#1e1e1e";

  /** Magma colour of t in [0, 1] as [r, g, b] (linear interpolation of the table). */
  function colormap(t) {
    t = t > 0 ? Math.min(t, 1) : 0;
    var n = MAGMA.length / 3 - 1, f = t * n, i = Math.min(Math.floor(f), n - 1), w = f - i;
    return [0, 1, 2].map(function (c) {
      return Math.round(MAGMA[3 * i + c] * (1 - w) + MAGMA[3 * (i + 1) + c] * w);
    });
  }

  var LUT = [];
  for (var k = 0; k < 256; k++) LUT.push(colormap(k / 255));

  /** The colour an error map shows for t in [0, 1] (the 256-entry table). */
  function errorColor(t) {
    return LUT[Math.round((t > 0 ? Math.min(t, 1) : 0) * 255)];
  }

  /** Linear value to 8-bit sRGB, as experiments/lib/store.py tonemap(). */
  function srgb8(x) {
    if (!(x > 0)) return 0;  // also NaN
    if (x >= 1) return 255;
    var s = x <= 0.0031308 ? 12.92 * x : 1.055 * Math.pow(x, 1 / 2.4) - 0.055;
    return Math.round(s * 255);
  }

  function fmt(x) {
    if (x === null || x === undefined || isNaN(x)) return "NaN";
    if (x === 0) return "0";
    var a = Math.abs(x);
    return a >= 1e4 || a < 1e-3 ? x.toExponential(4) : x.toPrecision(5);
  }

  // ------------------------------------------------------------- data blobs

  var blobs = {};

  function blobEntry(id) {
    var e = blobs[id];
    if (!e) {
      e = blobs[id] = {};
      e.promise = new Promise(function (resolve, reject) { e.resolve = resolve; e.reject = reject; });
    }
    return e;
  }

  /** Called by the data scripts: one base64 string per id. */
  function receive(id, base64) { blobEntry(id).resolve(base64); }

  var HALF = null;  // float16 bit pattern -> value, built on first use

  function halfTable() {
    if (!HALF) {
      HALF = new Float32Array(65536);
      for (var h = 0; h < 65536; h++) {
        var sign = h & 0x8000 ? -1 : 1, e = (h >> 10) & 0x1f, f = h & 0x3ff;
        HALF[h] = e === 0 ? sign * f * Math.pow(2, -24) :
          e === 31 ? (f ? NaN : sign * Infinity) : sign * (1 + f / 1024) * Math.pow(2, e - 15);
      }
    }
    return HALF;
  }

  /** base64 of zlib-compressed little-endian f32 or f16 values -> Promise of a Float32Array. */
  function decode(base64, type) {
    if (type !== "f32" && type !== "f16") return Promise.reject(new Error("unknown data type " + type));
    if (typeof DecompressionStream === "undefined")
      return Promise.reject(new Error("this browser has no DecompressionStream"));
    var bin = atob(base64), bytes = new Uint8Array(bin.length);
    for (var i = 0; i < bin.length; i++) bytes[i] = bin.charCodeAt(i);
    var stream = new Blob([bytes]).stream().pipeThrough(new DecompressionStream("deflate"));
    return new Response(stream).arrayBuffer().then(function (buf) {
      if (type === "f32") return new Float32Array(buf);
      var bits = new Uint16Array(buf), table = halfTable(), out = new Float32Array(bits.length);
      for (var j = 0; j < bits.length; j++) out[j] = table[bits[j]];
      return out;
    });
  }

  /** Promise of the Float32Array of blob {id, src, type}; injects its script once. */
  function loadBlob(ref) {
    var e = blobEntry(ref.id);
    if (!e.script) {
      e.script = document.createElement("script");
      e.script.src = ref.src;
      e.script.async = true;
      e.script.onerror = function () { e.reject(new Error("viewer data missing: " + ref.src)); };
      document.head.appendChild(e.script);
    }
    if (!e.decoded) e.decoded = e.promise.then(function (b64) { return decode(b64, ref.type); });
    return e.decoded;
  }

  // ---------------------------------------------------------------- viewer

  var viewers = [], hovered = null, lastClicked = null;

  function el(tag, cls, text) {
    var node = document.createElement(tag);
    if (cls) node.className = cls;
    if (text !== undefined) node.textContent = text;
    return node;
  }

  function button(text, title, onclick) {
    var b = el("button", "vrv-btn", text);
    b.type = "button";
    b.tabIndex = -1;  // keys go to the viewer, Space never "clicks" a focused button
    b.title = title;
    b.addEventListener("mousedown", function (ev) { ev.preventDefault(); });
    b.addEventListener("click", onclick);
    return b;
  }

  function Viewer(root) {
    this.root = root;
    this.m = JSON.parse(root.querySelector("script.vrv-manifest").textContent);
    this.W = this.m.width;
    this.H = this.m.height;
    this.n = this.m.images.length;
    this.sel = 0;
    this.prev = this.n > 1 ? 1 : 0;
    this.mode = "image";
    this.metric = "relmse";
    this.stops = 0;
    this.grid = false;
    this.view = null;       // {s, ox, oy}: screen px per image px, image origin in the pane
    this.pixels = null;     // Float32Array (RGB) per image once loaded
    this.errors = {};       // metric -> array of Float32Array, once loaded
    this.errorLoads = {};
    this.cache = {};        // tone-mapped / colour-mapped canvases
    this.pointer = null;    // last pointer position {pane, x, y}
    this.drag = null;
    this.panes = [];
    this.build();
    this.setState("idle");
  }

  Viewer.prototype.build = function () {
    var self = this, m = this.m, root = this.root;
    root.classList.add("vrv-live");
    var bar = el("div", "vrv-bar");
    if (m.title) bar.appendChild(el("span", "vrv-title", m.title));
    this.labels = m.images.map(function (im, i) {
      var b = button("", "show " + im.label + (i < 9 ? " (key " + (i + 1) + ")" : ""),
        function () { self.select(i); });
      b.classList.add("vrv-label");
      b.dataset.index = i;
      if (i < 9) b.appendChild(el("kbd", "", String(i + 1)));
      b.appendChild(document.createTextNode(" " + im.label));
      if (im.note) b.appendChild(el("span", "vrv-note", im.note));
      bar.appendChild(b);
      return b;
    });
    this.panesEl = el("div", "vrv-panes");
    this.panesEl.style.aspectRatio = this.W + " / " + this.H;
    var placeholder = root.querySelector(".vrv-placeholder");
    if (placeholder) placeholder.remove();
    var status = el("div", "vrv-status");
    this.readoutEl = el("div", "vrv-readout", "");
    this.evEl = el("span", "vrv-ev");
    var controls = el("span", "vrv-controls");
    controls.appendChild(button("−", "exposure down one stop (-)", function () { self.expose(-1); }));
    controls.appendChild(this.evEl);
    controls.appendChild(button("+", "exposure up one stop (+)", function () { self.expose(1); }));
    if (this.hasErrors()) {
      this.modeBtn = button("error map", "toggle the error map (e)", function () { self.toggleError(); });
      this.metricBtn = button("", "switch the error metric (m)", function () { self.switchMetric(); });
      controls.appendChild(this.modeBtn);
      controls.appendChild(this.metricBtn);
    }
    if (this.n > 1) {
      this.gridBtn = button("side by side", "toggle side by side (g)", function () { self.toggleGrid(); });
      controls.appendChild(this.gridBtn);
    }
    controls.appendChild(button("reset", "fit the image, exposure 0 (r)", function () { self.reset(); }));
    this.zoomEl = el("span", "vrv-zoom");
    controls.appendChild(this.zoomEl);
    this.barEl = el("span", "vrv-colorbar");
    this.barLo = el("span", "vrv-tick");
    this.barCanvas = el("canvas");
    this.barCanvas.width = 256;
    this.barCanvas.height = 1;
    this.barHi = el("span", "vrv-tick");
    this.barEl.appendChild(this.barLo);
    this.barEl.appendChild(this.barCanvas);
    this.barEl.appendChild(this.barHi);
    var img = this.barCanvas.getContext("2d").createImageData(256, 1);
    for (var i = 0; i < 256; i++) {
      img.data[4 * i] = LUT[i][0]; img.data[4 * i + 1] = LUT[i][1];
      img.data[4 * i + 2] = LUT[i][2]; img.data[4 * i + 3] = 255;
    }
    this.barCanvas.getContext("2d").putImageData(img, 0, 0);
    controls.appendChild(this.barEl);
    status.appendChild(controls);
    var help = el("div", "vrv-help", HELP);
    var caption = root.querySelector("figcaption");
    root.insertBefore(bar, caption);
    root.insertBefore(this.panesEl, caption);
    root.insertBefore(status, caption);
    root.insertBefore(this.readoutEl, caption);
    root.insertBefore(help, caption);

    root.addEventListener("mouseenter", function () { hovered = self; });
    root.addEventListener("mouseleave", function () { if (hovered === self) hovered = null; });
    root.addEventListener("pointerdown", function () { lastClicked = self; self.load(); }, true);
    this.updateControls();
  };

  Viewer.prototype.hasErrors = function () {
    return this.m.images.some(function (im) { return !!im.errors; });
  };

  Viewer.prototype.setState = function (state) { this.root.dataset.state = state; };

  Viewer.prototype.load = function () {
    var self = this;
    if (this.loading) return this.loading;
    this.setState("loading");
    this.loading = Promise.all(this.m.images.map(function (im) {
      return loadBlob(im.data);
    })).then(function (arrays) {
      arrays.forEach(function (a, i) {
        if (a.length !== 3 * self.W * self.H)
          throw new Error("image " + self.m.images[i].label + " has " + a.length + " values, expected " +
            3 * self.W * self.H);
      });
      self.pixels = arrays;
      self.setState("ready");
      self.layoutPanes();
      self.draw();
      self.readout();
    }).catch(function (err) { self.fail(err); });
    return this.loading;
  };

  Viewer.prototype.loadErrors = function (metric) {
    var self = this;
    if (!this.errorLoads[metric]) {
      this.errorLoads[metric] = Promise.all(this.m.images.map(function (im) {
        return im.errors ? loadBlob(im.errors[metric]) : Promise.resolve(null);
      })).then(function (arrays) {
        self.errors[metric] = arrays;
        self.draw();
        self.readout();
      }).catch(function (err) { self.fail(err); });
    }
    return this.errorLoads[metric];
  };

  Viewer.prototype.fail = function (err) {
    this.setState("failed");
    this.panesEl.textContent = "Viewer could not load its data: " + err.message;
    console.error("viewer " + this.root.dataset.viewer + ": " + err.message);
  };

  Viewer.prototype.layoutPanes = function () {
    var self = this, count = this.grid ? this.n : 1;
    while (this.panes.length > count) this.panesEl.removeChild(this.panes.pop().canvas);
    while (this.panes.length < count) this.panes.push(this.makePane(this.panes.length));
    var width = this.panesEl.clientWidth || 640, gap = 6;
    var cols = this.grid ? Math.min(count, width >= 900 ? 3 : 2) : 1;
    var rows = Math.ceil(count / cols);
    var pw = Math.floor((width - gap * (cols - 1)) / cols);
    var ph = Math.round(pw * this.H / this.W);
    if (!this.grid) ph = Math.min(ph, Math.round(0.8 * window.innerHeight));
    var dpr = window.devicePixelRatio || 1;
    this.panesEl.style.aspectRatio = "auto";
    this.panesEl.style.height = (rows * ph + (rows - 1) * gap) + "px";
    this.panesEl.style.gridTemplateColumns = "repeat(" + cols + ", " + pw + "px)";
    this.panes.forEach(function (p) {
      p.w = pw; p.h = ph;
      p.canvas.style.width = pw + "px";
      p.canvas.style.height = ph + "px";
      p.canvas.width = Math.round(pw * dpr);
      p.canvas.height = Math.round(ph * dpr);
    });
    this.view = null;
    this.fit();
    void self;
  };

  Viewer.prototype.makePane = function (index) {
    var self = this, canvas = el("canvas", "vrv-canvas"), pane = {canvas: canvas, index: index};
    this.panesEl.appendChild(canvas);
    canvas.addEventListener("wheel", function (ev) {
      if (!self.view) return;
      ev.preventDefault();
      var dy = ev.deltaY * (ev.deltaMode === 1 ? 33 : ev.deltaMode === 2 ? 400 : 1);
      self.zoomAt(ev.offsetX, ev.offsetY, Math.pow(2, -dy / 200));
    }, {passive: false});
    canvas.addEventListener("pointerdown", function (ev) {
      if (ev.button !== 0 || !self.view) return;
      ev.preventDefault();
      self.drag = {x: ev.clientX, y: ev.clientY, ox: self.view.ox, oy: self.view.oy};
      canvas.setPointerCapture(ev.pointerId);
    });
    canvas.addEventListener("pointermove", function (ev) {
      if (self.drag && self.view) {
        self.view.ox = self.drag.ox + ev.clientX - self.drag.x;
        self.view.oy = self.drag.oy + ev.clientY - self.drag.y;
        self.draw();
      }
      self.pointer = {pane: pane, x: ev.offsetX, y: ev.offsetY};
      self.readout();
    });
    canvas.addEventListener("pointerup", function () { self.drag = null; });
    canvas.addEventListener("pointercancel", function () { self.drag = null; });
    canvas.addEventListener("pointerleave", function () {
      if (!self.drag) { self.pointer = null; self.readout(); }
    });
    return pane;
  };

  Viewer.prototype.fit = function () {
    var p = this.panes[0];
    if (!p) return;
    var s = Math.min(p.w / this.W, p.h / this.H);
    this.fitScale = s;
    this.view = {s: s, ox: (p.w - this.W * s) / 2, oy: (p.h - this.H * s) / 2};
  };

  Viewer.prototype.zoomAt = function (x, y, factor) {
    var v = this.view;
    var s = Math.min(Math.max(v.s * factor, this.fitScale * MIN_ZOOM_OF_FIT), MAX_ZOOM);
    v.ox = x - (x - v.ox) * s / v.s;
    v.oy = y - (y - v.oy) * s / v.s;
    v.s = s;
    this.draw();
    this.readout();
  };

  Viewer.prototype.imageOf = function (pane) { return this.grid ? pane.index : this.sel; };

  /** The canvas (W x H) a pane draws for image i, or null while its data loads. */
  Viewer.prototype.source = function (i) {
    var key, W = this.W, H = this.H, n = W * H, c, img, d, j;
    if (this.mode === "error") {
      var maps = this.errors[this.metric];
      if (!maps) { this.loadErrors(this.metric); return null; }
      key = "err|" + this.metric + "|" + i;
      if (this.cache[key]) return this.cache[key];
      var e = maps[i], t = this.normalizer();
      c = el("canvas"); c.width = W; c.height = H;
      img = c.getContext("2d").createImageData(W, H); d = img.data;
      for (j = 0; j < n; j++) {
        var rgb = errorColor(e ? t(e[j]) : 0);
        d[4 * j] = rgb[0]; d[4 * j + 1] = rgb[1]; d[4 * j + 2] = rgb[2]; d[4 * j + 3] = 255;
      }
    } else {
      key = "img|" + this.stops + "|" + i;
      if (this.cache[key]) return this.cache[key];
      var px = this.pixels[i], k = Math.pow(2, this.stops);
      c = el("canvas"); c.width = W; c.height = H;
      img = c.getContext("2d").createImageData(W, H); d = img.data;
      for (j = 0; j < n; j++) {
        d[4 * j] = srgb8(px[3 * j] * k);
        d[4 * j + 1] = srgb8(px[3 * j + 1] * k);
        d[4 * j + 2] = srgb8(px[3 * j + 2] * k);
        d[4 * j + 3] = 255;
      }
    }
    c.getContext("2d").putImageData(img, 0, 0);
    this.cache[key] = c;
    return c;
  };

  /** Error value -> [0, 1] for the colour map: log scale for relMSE, linear for FLIP. */
  Viewer.prototype.normalizer = function () {
    var r = this.m.ranges[this.metric];
    if (this.metric === "relmse") {
      return function (e) { return e > 0 ? (Math.log10(e) - r[0]) / (r[1] - r[0]) : 0; };
    }
    return function (e) { return (e - r[0]) / (r[1] - r[0]); };
  };

  Viewer.prototype.draw = function () {
    if (!this.pixels || !this.view) { this.updateControls(); return; }
    var self = this, v = this.view, W = this.W, H = this.H, drawn = [];
    var dpr = window.devicePixelRatio || 1;
    this.panes.forEach(function (p) {
      var i = self.imageOf(p), src = self.source(i), ctx = p.canvas.getContext("2d");
      ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
      ctx.fillStyle = BACKGROUND;
      ctx.fillRect(0, 0, p.w, p.h);
      if (!src) { drawn.push("loading"); return; }
      // only the visible source rectangle, pixel-exact (nearest) when magnified
      var x0 = Math.max(0, Math.floor(-v.ox / v.s)), y0 = Math.max(0, Math.floor(-v.oy / v.s));
      var x1 = Math.min(W, Math.ceil((p.w - v.ox) / v.s)), y1 = Math.min(H, Math.ceil((p.h - v.oy) / v.s));
      ctx.imageSmoothingEnabled = v.s < 1;
      if (x1 > x0 && y1 > y0)
        ctx.drawImage(src, x0, y0, x1 - x0, y1 - y0,
          v.ox + x0 * v.s, v.oy + y0 * v.s, (x1 - x0) * v.s, (y1 - y0) * v.s);
      if (self.grid) {
        ctx.font = "12px sans-serif";
        var label = (i < 9 ? (i + 1) + " " : "") + self.m.images[i].label;
        ctx.fillStyle = "rgba(0,0,0,.6)";
        ctx.fillRect(0, 0, ctx.measureText(label).width + 10, 18);
        ctx.fillStyle = "#fff";
        ctx.fillText(label, 5, 13);
      }
      drawn.push(self.mode === "error" ? "error:" + self.metric + ":" + i : "image:" + i);
    });
    this.root.dataset.drawn = drawn.join(",");
    this.updateControls();
  };

  Viewer.prototype.updateControls = function () {
    var self = this, root = this.root;
    root.dataset.selected = this.sel;
    root.dataset.mode = this.mode;
    root.dataset.metric = this.metric;
    root.dataset.exposure = this.stops;
    root.dataset.layout = this.grid ? "grid" : "single";
    root.dataset.zoom = this.view ? this.view.s : "";
    this.labels.forEach(function (b, i) {
      b.classList.toggle("vrv-active", self.grid || i === self.sel);
    });
    this.evEl.textContent = "EV " + (this.stops > 0 ? "+" : this.stops < 0 ? "−" : "±") + Math.abs(this.stops);
    this.zoomEl.textContent = this.view ? "zoom " + fmt(this.view.s) + "×" : "";
    if (this.gridBtn) this.gridBtn.classList.toggle("vrv-active", this.grid);
    if (this.modeBtn) {
      this.modeBtn.classList.toggle("vrv-active", this.mode === "error");
      this.metricBtn.textContent = METRICS[this.metric];
    }
    var r = this.m.ranges && this.m.ranges[this.metric];
    this.barEl.style.display = this.mode === "error" && r ? "" : "none";
    if (r) {
      this.barLo.textContent = this.metric === "relmse" ? "1e" + r[0] : String(r[0]);
      this.barHi.textContent = (this.metric === "relmse" ? "1e" + r[1] : String(r[1])) +
        (this.metric === "relmse" ? " relMSE per pixel (log)" : " FLIP");
    }
  };

  Viewer.prototype.readout = function () {
    var p = this.pointer, v = this.view, root = this.root;
    if (!p || !v || !this.pixels) { this.readoutEl.textContent = ""; delete root.dataset.readout; return; }
    var x = Math.floor((p.x - v.ox) / v.s), y = Math.floor((p.y - v.oy) / v.s);
    if (x < 0 || y < 0 || x >= this.W || y >= this.H) {
      this.readoutEl.textContent = ""; delete root.dataset.readout; return;
    }
    var i = this.imageOf(p.pane), o = 3 * (y * this.W + x), px = this.pixels[i];
    var r = {x: x, y: y, image: i, rgb: [px[o], px[o + 1], px[o + 2]]};
    var text = this.m.images[i].label + " (" + x + ", " + y + ")  R " + fmt(r.rgb[0]) +
      "  G " + fmt(r.rgb[1]) + "  B " + fmt(r.rgb[2]);
    var maps = this.errors[this.metric];
    if (this.mode === "error" && maps) {
      r.metric = this.metric;
      r.error = maps[i] ? maps[i][y * this.W + x] : 0;
      text += "  " + METRICS[this.metric] + " " + fmt(r.error);
    }
    this.readoutEl.textContent = text;
    root.dataset.readout = JSON.stringify(r);
  };

  Viewer.prototype.select = function (i) {
    if (i < 0 || i >= this.n) return;
    if (i !== this.sel) { this.prev = this.sel; this.sel = i; }
    this.refresh();
  };

  Viewer.prototype.flip = function () { this.select(this.prev); };

  Viewer.prototype.expose = function (delta) {
    var self = this;
    this.stops += delta;
    Object.keys(this.cache).forEach(function (k) { if (k.indexOf("img|") === 0) delete self.cache[k]; });
    this.refresh();
  };

  Viewer.prototype.toggleError = function () {
    if (!this.hasErrors()) return;
    this.mode = this.mode === "error" ? "image" : "error";
    this.refresh();
  };

  Viewer.prototype.switchMetric = function () {
    this.metric = this.metric === "relmse" ? "flip" : "relmse";
    this.refresh();
  };

  Viewer.prototype.toggleGrid = function () {
    if (this.n < 2) return;
    this.grid = !this.grid;
    this.pointer = null;
    if (this.pixels) this.layoutPanes();
    this.refresh();
  };

  Viewer.prototype.reset = function () {
    this.stops = 0;
    this.cache = {};
    this.fit();
    this.refresh();
  };

  Viewer.prototype.refresh = function () {
    this.load();
    this.draw();
    this.readout();
  };

  /** Handle one key; true when it was the viewer's. */
  Viewer.prototype.key = function (key) {
    if (key >= "1" && key <= "9") { this.select(key.charCodeAt(0) - 49); return true; }
    switch (key) {
      case " ": this.flip(); return true;
      case "+": case "=": this.expose(1); return true;
      case "-": case "_": this.expose(-1); return true;
      case "e": case "E": this.toggleError(); return true;
      case "m": case "M": this.switchMetric(); return true;
      case "g": case "G": this.toggleGrid(); return true;
      case "r": case "R": this.reset(); return true;
    }
    return false;
  };

  document.addEventListener("keydown", function (ev) {
    if (ev.ctrlKey || ev.metaKey || ev.altKey) return;
    var t = ev.target;
    if (t && (t.isContentEditable || /^(INPUT|TEXTAREA|SELECT)$/.test(t.tagName))) return;
    var v = hovered || lastClicked;
    if (v && v.key(ev.key)) ev.preventDefault();
  });

  window.addEventListener("resize", function () {
    viewers.forEach(function (v) { if (v.pixels) { v.layoutPanes(); v.draw(); } });
  });

  function init() {
    var roots = document.querySelectorAll("[data-viewer]");
    var observer = "IntersectionObserver" in window ? new IntersectionObserver(function (entries) {
      entries.forEach(function (entry) {
        if (entry.isIntersecting) {
          observer.unobserve(entry.target);
          entry.target.vrViewer.load();
        }
      });
    }, {rootMargin: "300px 0px"}) : null;
    Array.prototype.forEach.call(roots, function (root) {
      if (root.vrViewer) return;
      var v;
      try {
        v = new Viewer(root);
      } catch (err) {
        console.error("viewer " + root.dataset.viewer + ": bad manifest: " + err.message);
        return;
      }
      root.vrViewer = v;
      viewers.push(v);
      if (observer) observer.observe(root); else v.load();
    });
  }

  window.VRViewer = {blob: receive, colormap: colormap, errorColor: errorColor, srgb8: srgb8,
    viewers: viewers, init: init};
  if (document.readyState === "loading") document.addEventListener("DOMContentLoaded", init);
  else init();
})();
