// pgi report viewer: flip between the reference and each method (number keys), exposure
// slider, zoom (wheel) and pan (drag) synchronised across the three panels. No dependencies;
// works from file://. Data: window.PGI_DATA (written by compare.report.build), images as
// base64 RGBE (4 bytes per pixel, linear HDR).
(function () {
  "use strict";
  var D = window.PGI_DATA;
  var root = document.getElementById("viewer");
  if (!D || !root) {
    if (root) root.textContent = "viewer data missing";
    return;
  }
  var W = D.width, H = D.height, N = W * H;

  function decode(b64) {
    var bin = atob(b64), out = new Float32Array(N * 3);
    for (var i = 0; i < N; i++) {
      var e = bin.charCodeAt(4 * i + 3);
      if (e === 0) continue;
      var f = Math.pow(2, e - 136);
      out[3 * i] = (bin.charCodeAt(4 * i) + 0.5) * f;
      out[3 * i + 1] = (bin.charCodeAt(4 * i + 1) + 0.5) * f;
      out[3 * i + 2] = (bin.charCodeAt(4 * i + 2) + 0.5) * f;
    }
    return out;
  }
  var cache = {};
  function pixels(method, budget) {
    var key = method === "reference" ? "reference" : method + "@" + budget;
    if (!cache[key]) {
      var src = method === "reference" ? D.reference : (D.images[method] || {})[budget];
      cache[key] = src ? decode(src) : null;
    }
    return cache[key];
  }

  // ---- state -----------------------------------------------------------------------------
  var entries = ["reference"].concat(D.methods); // key 0 = reference, 1.. = methods
  var S = {
    sel: D.methods.length ? 1 : 0,
    budget: D.budgets.length - 1,
    ev: D.exposure || 0,
    scale: 1, tx: 0, ty: 0, // shared view transform (image px -> canvas px)
  };

  // ---- DOM -------------------------------------------------------------------------------
  function el(tag, attrs, parent) {
    var n = document.createElement(tag);
    for (var k in attrs || {}) {
      if (k === "text") n.textContent = attrs[k];
      else n.setAttribute(k, attrs[k]);
    }
    if (parent) parent.appendChild(n);
    return n;
  }
  var bar = el("div", { "class": "vbar" }, root);
  var keys = el("div", { "class": "vkeys" }, bar);
  var buttons = entries.map(function (name, i) {
    var b = el("button", { type: "button", text: (i < 10 ? i + ": " : "") + name }, keys);
    b.addEventListener("click", function () { select(i); });
    return b;
  });
  var ctl = el("div", { "class": "vctl" }, bar);
  el("label", { text: "budget " }, ctl);
  var budgetSel = el("select", { id: "v-budget" }, ctl);
  D.budgets.forEach(function (b, i) { el("option", { value: i, text: b + " s" }, budgetSel); });
  budgetSel.addEventListener("change", function () { S.budget = +budgetSel.value; draw(); });
  el("label", { text: " exposure " }, ctl);
  var evIn = el("input", { type: "range", min: -12, max: 12, step: 0.25, id: "v-exposure" }, ctl);
  var evOut = el("span", { "class": "vev" }, ctl);
  evIn.addEventListener("input", function () { S.ev = +evIn.value; draw(); });
  var reset = el("button", { type: "button", text: "fit" }, ctl);
  reset.addEventListener("click", function () { fit(); draw(); });
  var panes = el("div", { "class": "vpanes" }, root);
  function pane(label) {
    var box = el("figure", { "class": "vpane" }, panes);
    var c = el("canvas", { width: 10, height: 10 }, box);
    var cap = el("figcaption", { text: label }, box);
    return { canvas: c, cap: cap, off: document.createElement("canvas") };
  }
  var P = [pane("selected"), pane("reference"), pane("error")];
  var status = el("div", { "class": "vstatus" }, root);
  P.forEach(function (p) { p.off.width = W; p.off.height = H; });

  // ---- drawing ---------------------------------------------------------------------------
  function srgb(v) {
    v = v <= 0 ? 0 : v >= 1 ? 1 : v;
    return v <= 0.0031308 ? 12.92 * v : 1.055 * Math.pow(v, 1 / 2.4) - 0.055;
  }
  var LUT = D.colormap; // 256 x [r,g,b] 0..255 (inferno)
  function paintImage(p, px) {
    var ctx = p.off.getContext("2d"), im = ctx.createImageData(W, H), d = im.data;
    var k = Math.pow(2, S.ev);
    for (var i = 0; i < N; i++) {
      d[4 * i] = 255 * srgb(px[3 * i] * k) + 0.5;
      d[4 * i + 1] = 255 * srgb(px[3 * i + 1] * k) + 0.5;
      d[4 * i + 2] = 255 * srgb(px[3 * i + 2] * k) + 0.5;
      d[4 * i + 3] = 255;
    }
    ctx.putImageData(im, 0, 0);
  }
  function paintError(p, px, ref) {
    var ctx = p.off.getContext("2d"), im = ctx.createImageData(W, H), d = im.data;
    var lo = Math.log10(D.err_lo), hi = Math.log10(D.err_hi), sum = 0;
    for (var i = 0; i < N; i++) {
      var e = 0;
      for (var c = 0; c < 3; c++) {
        var r = ref[3 * i + c], x = px[3 * i + c];
        e += (x - r) * (x - r) / (r * r + 0.01);
      }
      e /= 3; sum += e;
      var t = e > 0 ? (Math.log10(e) - lo) / (hi - lo) : 0;
      var j = Math.max(0, Math.min(255, Math.round(255 * t)));
      d[4 * i] = LUT[j][0]; d[4 * i + 1] = LUT[j][1]; d[4 * i + 2] = LUT[j][2]; d[4 * i + 3] = 255;
    }
    ctx.putImageData(im, 0, 0);
    return sum / N;
  }
  function blit(p) {
    var c = p.canvas, ctx = c.getContext("2d");
    ctx.setTransform(1, 0, 0, 1, 0, 0);
    ctx.fillStyle = "#222"; ctx.fillRect(0, 0, c.width, c.height);
    ctx.imageSmoothingEnabled = S.scale < 1;
    ctx.setTransform(S.scale, 0, 0, S.scale, S.tx, S.ty);
    ctx.drawImage(p.off, 0, 0);
  }
  function blitAll() { P.forEach(blit); }
  function draw() {
    var name = entries[S.sel], budget = D.budgets[S.budget];
    var ref = pixels("reference"), px = pixels(name, budget);
    buttons.forEach(function (b, i) { b.className = i === S.sel ? "on" : ""; });
    budgetSel.value = String(S.budget);
    evIn.value = String(S.ev);
    evOut.textContent = (S.ev >= 0 ? "+" : "") + S.ev.toFixed(2) + " EV";
    var label = name === "reference" ? "reference" : name + " @ " + budget + " s";
    var taken = name === "reference" ? NaN : ((D.seconds || {})[name] || {})[budget];
    // as in the tables: a snapshot far off its budget is not an equal-time image
    var offBudget = Math.abs(taken - budget) > D.off_budget * budget ?
      " (this image's snapshot at " + taken.toPrecision(3) + " s: not equal time)" : "";
    if (!px) {
      P[0].off.getContext("2d").clearRect(0, 0, W, H);
      P[0].cap.textContent = label + " (missing)";
    } else {
      paintImage(P[0], px);
      P[0].cap.textContent = label + offBudget;
    }
    paintImage(P[1], ref);
    var err = px ? paintError(P[2], px, ref) : NaN;
    // the mean the tables have: of the full-size image, not of the map shown
    var full = (D.relmse[name] || {})[budget];  // none for the reference itself
    if (full !== undefined) err = full;
    var size = D.film[0] !== W || D.film[1] !== H ?
      " of the " + D.film[0] + "×" + D.film[1] + " image; map shown at " + W + "×" + H : "";
    P[2].cap.textContent = "relMSE per pixel of " + label + " (mean " + err.toPrecision(3) +
      size + "; log scale " + D.err_lo.toPrecision(2) + " … " + D.err_hi.toPrecision(2) + ")";
    blitAll();
    root.dataset.method = name;
    root.dataset.budget = String(budget);
    root.dataset.exposure = String(S.ev);
  }
  function select(i) {
    if (i >= 0 && i < entries.length) { S.sel = i; draw(); }
  }

  // ---- layout, zoom and pan (one transform for all panels) -------------------------------
  function size() {
    var w = Math.max(120, Math.floor((panes.clientWidth - 24) / 3));
    var h = Math.round(w * H / W);
    P.forEach(function (p) { p.canvas.width = w; p.canvas.height = h; });
  }
  function fit() {
    var c = P[0].canvas;
    S.scale = Math.min(c.width / W, c.height / H);
    S.tx = (c.width - W * S.scale) / 2;
    S.ty = (c.height - H * S.scale) / 2;
  }
  var drag = null;
  P.forEach(function (p) {
    var c = p.canvas;
    c.addEventListener("wheel", function (ev) {
      ev.preventDefault();
      var r = c.getBoundingClientRect(), mx = ev.clientX - r.left, my = ev.clientY - r.top;
      var f = Math.pow(1.0015, -ev.deltaY);
      var s = Math.max(0.1, Math.min(64, S.scale * f));
      S.tx = mx - (mx - S.tx) * s / S.scale;
      S.ty = my - (my - S.ty) * s / S.scale;
      S.scale = s;
      blitAll();
    }, { passive: false });
    c.addEventListener("mousedown", function (ev) {
      drag = { x: ev.clientX, y: ev.clientY, tx: S.tx, ty: S.ty };
    });
    c.addEventListener("dblclick", function () { fit(); blitAll(); });
    c.addEventListener("mousemove", function (ev) {
      var r = c.getBoundingClientRect();
      var ix = Math.floor((ev.clientX - r.left - S.tx) / S.scale);
      var iy = Math.floor((ev.clientY - r.top - S.ty) / S.scale);
      if (ix < 0 || iy < 0 || ix >= W || iy >= H) return;
      var px = pixels(entries[S.sel], D.budgets[S.budget]), ref = pixels("reference"), j = 3 * (iy * W + ix);
      function rgb(a) { return a ? [a[j], a[j + 1], a[j + 2]].map(function (v) { return v.toPrecision(4); }).join(", ") : "–"; }
      status.textContent = "pixel (" + ix + ", " + iy + ")  " + entries[S.sel] + ": " + rgb(px) +
        "   reference: " + rgb(ref);
    });
  });
  window.addEventListener("mousemove", function (ev) {
    if (!drag) return;
    S.tx = drag.tx + ev.clientX - drag.x;
    S.ty = drag.ty + ev.clientY - drag.y;
    blitAll();
  });
  window.addEventListener("mouseup", function () { drag = null; });
  window.addEventListener("keydown", function (ev) {
    // the browser's own shortcuts (Ctrl+F, Ctrl+0, Alt+Left, ...) stay the browser's, and
    // keys act on the viewer only while some of it is on screen
    if (ev.ctrlKey || ev.altKey || ev.metaKey) return;
    var box = root.getBoundingClientRect();
    if (box.bottom <= 0 || box.top >= window.innerHeight) return;
    if (ev.target && (ev.target.tagName === "INPUT" || ev.target.tagName === "SELECT") &&
        ev.key !== "Escape") {
      if (!/^[0-9]$/.test(ev.key)) return;
    }
    var k = ev.key;
    if (/^[0-9]$/.test(k)) { select(+k); }
    else if (k === "ArrowLeft" || k === "[") { S.budget = Math.max(0, S.budget - 1); draw(); }
    else if (k === "ArrowRight" || k === "]") { S.budget = Math.min(D.budgets.length - 1, S.budget + 1); draw(); }
    else if (k === "+" || k === "=") { S.ev = Math.min(12, S.ev + 0.5); draw(); }
    else if (k === "-") { S.ev = Math.max(-12, S.ev - 0.5); draw(); }
    else if (k === "f") { fit(); blitAll(); }
    else if (k === "e") { S.ev = D.exposure || 0; draw(); }
    else return;
    ev.preventDefault();
  });
  window.addEventListener("resize", function () { size(); fit(); blitAll(); });
  size(); fit(); draw();
  window.PGI_VIEWER = { state: S, select: select, draw: draw };
  root.dataset.ready = "1";
})();
