/* busarm dashboard page: the arm drawn from its joints (forward kinematics: the link
 * points of each `state`), seen from above and from the side. app.js calls
 * `window.busarmArmView.draw(points, robot)` when the arm moved.
 */
'use strict';

(() => {
  const $ = (id) => document.getElementById(id);

  /** Draw the arm's link points (mm, base first): top view and side view. */
  function drawArm(points, robot) {
    if (!points.length) return;
    const tableZ = robot && typeof robot.table_z_mm === 'number' ? robot.table_z_mm : 0;
    // The side view's horizontal axis: reach along the arm's heading (from the point that
    // reaches farthest from the base axis), signed so that reaching behind is negative.
    let ux = 1; let uy = 0; let best = 5;
    for (const [x, y] of points) {
      const r = Math.hypot(x, y);
      if (r > best) { best = r; ux = x / r; uy = y / r; }
    }
    const reach = points.reduce((a, p, i) => (i ? a + Math.hypot(
      p[0] - points[i - 1][0], p[1] - points[i - 1][1], p[2] - points[i - 1][2]) : 0), 0);
    const span = Math.max(200, reach - (points[1] ? points[1][2] : 0)) * 1.05;

    // Top: x forward = up on the screen, y left = left.
    view($('arm-top'), { left: -0.75 * span, right: 0.75 * span, bottom: -0.3 * span, top: span },
      (g, P) => {
        const c = P(0, 0);
        g.font = '10px sans-serif'; g.fillStyle = '#5c6577';
        for (let r = 100; r <= span; r += 100) {  // reach rings, every 100 mm
          const e = P(r, 0);
          g.strokeStyle = r % 200 ? '#262b35' : '#323846';
          g.beginPath(); g.arc(c[0], c[1], Math.abs(e[0] - c[0]), 0, Math.PI * 2); g.stroke();
          const at = P(0.5 * r, 0.87 * r);  // labelled front right, clear of the x axis
          g.fillText(`${r}`, at[0] + 2, at[1] - 2);
        }
        axes(g, P, [0, 80], 'x', [80, 0], 'y');
        chain(g, points.map((p) => P(-p[1], p[0])));
      });
    // Side: reach along the heading to the right, z up; the table as a line.
    const height = Math.max(reach, 400) * 1.05;
    view($('arm-side'), { left: -0.55 * span, right: span, bottom: tableZ - 40, top: height },
      (g, P) => {
        g.font = '10px sans-serif'; g.lineWidth = 1;
        for (let z = tableZ + 100; z <= height; z += 100) {  // heights above the table
          const l = P(-1e4, z); const r = P(1e4, z);
          g.strokeStyle = '#262b35';
          g.beginPath(); g.moveTo(l[0], l[1]); g.lineTo(r[0], r[1]); g.stroke();
          g.fillStyle = '#5c6577'; g.fillText(`z ${z - tableZ}`, 4, l[1] - 2);
        }
        const a = P(-1e4, tableZ); const b = P(1e4, tableZ);
        g.strokeStyle = '#8a6d3b'; g.lineWidth = 2;
        g.beginPath(); g.moveTo(a[0], a[1]); g.lineTo(b[0], b[1]); g.stroke();
        g.fillStyle = '#8a6d3b'; g.font = '10px sans-serif'; g.fillText('table', 4, a[1] - 4);
        chain(g, points.map((p) => P(p[0] * ux + p[1] * uy, p[2])));
      });
  }

  function view(canvas, box, paint) {
    const ratio = window.devicePixelRatio || 1;
    const w = canvas.clientWidth || canvas.width;
    const h = canvas.clientHeight || canvas.height;
    if (canvas.width !== Math.round(w * ratio) || canvas.height !== Math.round(h * ratio)) {
      canvas.width = Math.round(w * ratio);
      canvas.height = Math.round(h * ratio);
    }
    const g = canvas.getContext('2d');
    g.setTransform(ratio, 0, 0, ratio, 0, 0);
    g.clearRect(0, 0, w, h);
    const pad = 8;
    const scale = Math.min((w - 2 * pad) / (box.right - box.left), (h - 2 * pad) / (box.top - box.bottom));
    const ox = pad + ((w - 2 * pad) - scale * (box.right - box.left)) / 2;
    const oy = pad + ((h - 2 * pad) - scale * (box.top - box.bottom)) / 2;
    const P = (u, v) => [ox + (u - box.left) * scale, oy + (box.top - v) * scale];
    g.lineCap = 'round'; g.lineJoin = 'round';
    paint(g, P);
  }

  function axes(g, P, xEnd, xLabel, yEnd, yLabel) {
    const o = P(0, 0);
    g.lineWidth = 1; g.font = '10px sans-serif';
    const arrow = (end, label, color) => {
      const e = P(...end);
      g.strokeStyle = color; g.fillStyle = color;
      g.beginPath(); g.moveTo(o[0], o[1]); g.lineTo(e[0], e[1]); g.stroke();
      g.fillText(label, e[0] + 3, e[1] + 3);
    };
    arrow(xEnd, xLabel, '#e05555');
    arrow([-yEnd[0], yEnd[1]], yLabel, '#55c070');
  }

  function chain(g, pts) {
    g.strokeStyle = '#4fa3ff'; g.lineWidth = 5;
    g.beginPath();
    pts.forEach((p, i) => (i ? g.lineTo(p[0], p[1]) : g.moveTo(p[0], p[1])));
    g.stroke();
    g.fillStyle = '#dfe3ea';
    for (const p of pts.slice(0, -1)) { g.beginPath(); g.arc(p[0], p[1], 3, 0, Math.PI * 2); g.fill(); }
    const tip = pts[pts.length - 1];
    g.fillStyle = '#f0b232';
    g.beginPath(); g.arc(tip[0], tip[1], 5, 0, Math.PI * 2); g.fill();
    const base = pts[0];
    g.fillStyle = '#8a93a3';
    g.fillRect(base[0] - 9, base[1] - 3, 18, 6);
  }

  window.busarmArmView = { draw: drawArm };
})();
