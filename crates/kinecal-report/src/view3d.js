// kinecal's 3-D view: the scene of a calibration drawn on a 2-D canvas, in the page itself (no
// library, nothing fetched). Drag to turn, wheel to zoom, arrow keys and +/- on the focused
// view, double-click to reset. The data is the JSON in #v3d-data (lengths in the page's unit).
(function () {
  "use strict";
  var data = JSON.parse(document.getElementById("v3d-data").textContent);
  var canvas = document.getElementById("v3d-canvas");
  var ctx = canvas.getContext && canvas.getContext("2d");
  if (!ctx) { return; }
  var pick = document.getElementById("v3d-posture");
  var toggles = document.querySelectorAll("#v3d input[type=checkbox]");
  var view = { yaw: -0.75, pitch: 0.4, zoom: 1, posture: 0 };
  var show = {};
  var colors = {
    calibrated: "#1f63c7", nominal: "#8c8c8c", points: "#222222", highlight: "#e08a00",
    after: "#d62728", before: "#ff7f0e", x: "#d62728", y: "#2ca02c", z: "#1f4fe0", grid: "#e4e4e4",
    camera: "#9433b3", board: "#4d4d4d", seen: "#00998a"
  };

  // What the view turns about, and how big it is: every robot node and every point.
  var lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
  function grow(p) {
    for (var k = 0; k < 3; k++) { lo[k] = Math.min(lo[k], p[k]); hi[k] = Math.max(hi[k], p[k]); }
  }
  data.postures.forEach(function (p) {
    p.calibrated.nodes.forEach(grow);
    if (p.nominal) { p.nominal.nodes.forEach(grow); }
    (p.cameras || []).concat(p.boards || []).forEach(function (m) {
      m.lines.forEach(function (l) { grow(l[0]); grow(l[1]); });
    });
  });
  data.points.forEach(function (p) { grow(p.measured); });
  data.frames.forEach(function (f) { grow(f.origin); });
  var centre = [0, 1, 2].map(function (k) { return (lo[k] + hi[k]) / 2; });
  var radius = Math.max(1e-9, Math.sqrt([0, 1, 2].reduce(function (s, k) {
    var d = hi[k] - lo[k]; return s + d * d;
  }, 0)) / 2);

  // A point of the scene (z up) on the canvas: turned by yaw about z, tilted by pitch, seen in
  // perspective from four radii away.
  function project(p) {
    var x = p[0] - centre[0], y = p[1] - centre[1], z = p[2] - centre[2];
    var cy = Math.cos(view.yaw), sy = Math.sin(view.yaw);
    var cp = Math.cos(view.pitch), sp = Math.sin(view.pitch);
    var x1 = cy * x - sy * y, y1 = sy * x + cy * y;
    var depth = y1 * cp - z * sp, up = y1 * sp + z * cp;
    var d = 4 * radius;
    var f = view.zoom * Math.min(canvas.width, canvas.height) / (1.6 * radius) * d / Math.max(d + depth, 1e-3 * d);
    return [canvas.width / 2 + x1 * f, canvas.height / 2 - up * f, depth];
  }
  function along(p, v, k) { return [p[0] + k * v[0], p[1] + k * v[1], p[2] + k * v[2]]; }
  function line(a, b, color, width, dash) {
    var p = project(a), q = project(b);
    ctx.strokeStyle = color; ctx.lineWidth = width; ctx.setLineDash(dash || []);
    ctx.beginPath(); ctx.moveTo(p[0], p[1]); ctx.lineTo(q[0], q[1]); ctx.stroke();
  }
  function dot(a, color, r, ring) {
    var p = project(a);
    ctx.beginPath(); ctx.arc(p[0], p[1], r, 0, 2 * Math.PI);
    if (ring) { ctx.strokeStyle = color; ctx.lineWidth = 2; ctx.setLineDash([]); ctx.stroke(); }
    else { ctx.fillStyle = color; ctx.fill(); }
  }
  function label(a, text, color, below) {
    var p = project(a);
    ctx.fillStyle = color; ctx.font = (12 * ratio) + "px sans-serif";
    ctx.fillText(text, p[0] + 4 * ratio, p[1] + (below ? 16 : -4) * ratio);
  }
  function skeleton(s, color, width, dash) {
    s.links.forEach(function (l) { line(s.nodes[l[0]], s.nodes[l[1]], color, width, dash); });
    s.joints.forEach(function (j) {
      var at = s.nodes[j[0]], half = data.reach / 40;
      line(along(at, j[1], -half), along(at, j[1], half), color, width / 2);
      dot(at, color, 2.5 * ratio);
    });
  }
  function frame(f, size, name) {
    ["x", "y", "z"].forEach(function (axis, k) {
      line(f.origin, along(f.origin, f.axes[k], size), colors[axis], 1.5 * ratio);
    });
    if (name) { label(f.origin, f.name, "#555", true); }
  }
  // The floor: a grid on the global frame's xy plane, in steps of the axes' length.
  function grid() {
    var step = data.axis;
    var x0 = Math.floor(lo[0] / step) * step, x1 = Math.ceil(hi[0] / step) * step;
    var y0 = Math.floor(lo[1] / step) * step, y1 = Math.ceil(hi[1] / step) * step;
    if ((x1 - x0) / step > 200 || (y1 - y0) / step > 200) { return; }
    for (var x = x0; x <= x1 + step / 2; x += step) { line([x, y0, 0], [x, y1, 0], colors.grid, ratio); }
    for (var y = y0; y <= y1 + step / 2; y += step) { line([x0, y, 0], [x1, y, 0], colors.grid, ratio); }
  }

  function draw() {
    ctx.setTransform(1, 0, 0, 1, 0, 0);
    ctx.fillStyle = "#ffffff";
    ctx.fillRect(0, 0, canvas.width, canvas.height);
    var posture = data.postures[view.posture];
    if (show.grid) { grid(); }
    if (show.frames) {
      data.frames.forEach(function (f) { frame(f, data.axis, true); });
      posture.calibrated.tools.forEach(function (f) { frame(f, data.axis / 2, false); });
      var o = data.frames[0];
      if (o) ["x", "y", "z"].forEach(function (axis, k) {
        label(along(o.origin, o.axes[k], data.axis), axis, colors[axis]);
      });
    }
    // Cameras (frustums) and boards (grids, the points seen at this posture dotted).
    if (show.cameras) {
      (posture.boards || []).forEach(function (b) {
        b.lines.forEach(function (l) { line(l[0], l[1], colors.board, ratio); });
        b.seen.forEach(function (p) { dot(p, colors.seen, 2 * ratio); });
        if (show.frames) { frame(b, data.axis / 2, false); }
        label(b.origin, b.name, colors.board, true);
      });
      (posture.cameras || []).forEach(function (c) {
        c.lines.forEach(function (l) { line(l[0], l[1], colors.camera, 1.5 * ratio); });
        if (show.frames) { frame(c, data.axis / 2, false); }
        label(c.origin, c.name, colors.camera, false);
      });
    }
    if (show.nominal && posture.nominal) { skeleton(posture.nominal, colors.nominal, 2 * ratio, [6 * ratio, 4 * ratio]); }
    if (show.points) {
      data.points.forEach(function (p) { dot(p.measured, colors.points, 1.6 * ratio); });
    }
    if (show.before) {
      data.points.forEach(function (p) {
        if (p.before) { line(p.measured, along(p.measured, p.before, data.scale_before), colors.before, ratio); }
      });
    }
    if (show.after) {
      data.points.forEach(function (p) {
        line(p.measured, along(p.measured, p.after, data.scale), colors.after, 1.2 * ratio);
      });
    }
    skeleton(posture.calibrated, colors.calibrated, 3 * ratio);
    if (show.points) {
      data.points.forEach(function (p) {
        if (p.posture === posture.index) { dot(p.measured, colors.highlight, 6 * ratio, true); }
      });
    }
    ctx.fillStyle = "#333"; ctx.font = (12 * ratio) + "px sans-serif";
    ctx.fillText(data.title + " at posture " + posture.label, 8 * ratio, 16 * ratio);
    ctx.fillText(data.caption, 8 * ratio, canvas.height - 8 * ratio);
  }

  // The canvas's pixels follow its size on the page and the screen's pixel ratio.
  var ratio = 1;
  function resize() {
    ratio = window.devicePixelRatio || 1;
    var w = canvas.clientWidth || 900;
    canvas.width = Math.round(w * ratio);
    canvas.height = Math.round(w * 0.6 * ratio);
    draw();
  }
  function read() {
    Array.prototype.forEach.call(toggles, function (t) { show[t.name] = t.checked; });
    view.posture = pick ? Number(pick.value) : 0;
    draw();
  }
  Array.prototype.forEach.call(toggles, function (t) { t.addEventListener("change", read); });
  if (pick) { pick.addEventListener("change", read); }

  var drag = null;
  canvas.addEventListener("pointerdown", function (e) {
    drag = [e.clientX, e.clientY];
    try { canvas.setPointerCapture(e.pointerId); } catch (err) { /* a pointer already gone */ }
  });
  canvas.addEventListener("pointermove", function (e) {
    if (!drag) { return; }
    view.yaw += (e.clientX - drag[0]) * 0.01;
    view.pitch = Math.max(-1.55, Math.min(1.55, view.pitch + (e.clientY - drag[1]) * 0.01));
    drag = [e.clientX, e.clientY];
    draw();
  });
  canvas.addEventListener("pointerup", function () { drag = null; });
  canvas.addEventListener("wheel", function (e) {
    e.preventDefault();
    view.zoom = Math.max(0.1, Math.min(200, view.zoom * Math.exp(-e.deltaY * 0.001)));
    draw();
  }, { passive: false });
  canvas.addEventListener("dblclick", function () {
    view.yaw = -0.75; view.pitch = 0.4; view.zoom = 1; draw();
  });
  canvas.addEventListener("keydown", function (e) {
    var k = { ArrowLeft: [-0.1, 0, 1], ArrowRight: [0.1, 0, 1], ArrowUp: [0, -0.1, 1],
      ArrowDown: [0, 0.1, 1], "+": [0, 0, 1.2], "=": [0, 0, 1.2], "-": [0, 0, 1 / 1.2] }[e.key];
    if (!k) { return; }
    e.preventDefault();
    view.yaw += k[0];
    view.pitch = Math.max(-1.55, Math.min(1.55, view.pitch + k[1]));
    view.zoom = Math.max(0.1, Math.min(200, view.zoom * k[2]));
    draw();
  });
  window.addEventListener("resize", resize);
  Array.prototype.forEach.call(toggles, function (t) { show[t.name] = t.checked; });
  resize();

  // How much was drawn, for a test in a headless browser: the pixels that are not background.
  try {
    var px = ctx.getImageData(0, 0, canvas.width, canvas.height).data, drawn = 0;
    for (var i = 0; i < px.length; i += 4) {
      if (px[i] < 250 || px[i + 1] < 250 || px[i + 2] < 250) { drawn++; }
    }
    canvas.setAttribute("data-drawn", String(drawn));
    canvas.setAttribute("data-pixels", String(canvas.width * canvas.height));
  } catch (e) { /* a canvas that cannot be read back is still drawn */ }
})();
