// wearnav's map drawing, shared by the live page (index.html) and track's static trajectory.html.
// A canvas with a metric grid (east/north metres about the origin: always works offline), optional
// OpenStreetMap raster tiles under it when the browser is online (fetched by the browser; a tile that
// fails is left out silently), the location fixes with their accuracy circles, and the path
// (coloured per point where colours are given). No library, nothing from a CDN.
"use strict";

const WearnavDraw = (() => {
  const EARTH_R = 6378137.0;  // WGS-84 equatorial radius (m): tiles are placed with a local
  // equirectangular approximation about the origin (sub-metre over a walk; the path itself is exact)
  const TILE_URL = "https://tile.openstreetmap.org/{z}/{x}/{y}.png";
  const tileCache = new Map();

  function niceStep(raw) {  // 1, 2, 5 × 10^k at or above raw
    const p = Math.pow(10, Math.floor(Math.log10(raw)));
    for (const m of [1, 2, 5, 10]) if (m * p >= raw) return m * p;
    return 10 * p;
  }

  // The view: metres → pixels, fitted to the points (x, y metres) with a margin, equal scales.
  function fitView(points, width, height) {
    let x0 = Infinity, x1 = -Infinity, y0 = Infinity, y1 = -Infinity;
    for (const [x, y] of points) {
      if (!isFinite(x) || !isFinite(y)) continue;
      x0 = Math.min(x0, x); x1 = Math.max(x1, x); y0 = Math.min(y0, y); y1 = Math.max(y1, y);
    }
    if (!isFinite(x0)) { x0 = -10; x1 = 10; y0 = -10; y1 = 10; }
    const span = Math.max(x1 - x0, y1 - y0, 20);
    const scale = Math.min(width, height) * 0.85 / span;  // px per metre
    return {scale, cx: (x0 + x1) / 2, cy: (y0 + y1) / 2, width, height};
  }

  function toPx(v, x, y) {
    return [v.width / 2 + (x - v.cx) * v.scale, v.height / 2 - (y - v.cy) * v.scale];
  }

  function drawGrid(ctx, v, light) {
    const step = niceStep(80 / v.scale);  // a line every ≥ 80 px
    const west = v.cx - v.width / 2 / v.scale, east = v.cx + v.width / 2 / v.scale;
    const south = v.cy - v.height / 2 / v.scale, north = v.cy + v.height / 2 / v.scale;
    ctx.strokeStyle = light ? "rgba(0,0,0,0.18)" : "#dde3ea";
    ctx.fillStyle = "#667";
    ctx.lineWidth = 1;
    ctx.font = "11px sans-serif";
    for (let x = Math.ceil(west / step) * step; x <= east; x += step) {
      const [px] = toPx(v, x, 0);
      ctx.beginPath(); ctx.moveTo(px, 0); ctx.lineTo(px, v.height); ctx.stroke();
      ctx.fillText(`${Math.round(x)} m`, px + 2, v.height - 4);
    }
    for (let y = Math.ceil(south / step) * step; y <= north; y += step) {
      const [, py] = toPx(v, 0, y);
      ctx.beginPath(); ctx.moveTo(0, py); ctx.lineTo(v.width, py); ctx.stroke();
      ctx.fillText(`${Math.round(y)} m`, 2, py - 2);
    }
    // scale bar
    const [bx, by] = [v.width - 20 - step * v.scale, 20];
    ctx.strokeStyle = "#223"; ctx.lineWidth = 3;
    ctx.beginPath(); ctx.moveTo(bx, by); ctx.lineTo(bx + step * v.scale, by); ctx.stroke();
    ctx.fillStyle = "#223"; ctx.fillText(`${step} m`, bx, by + 14);
  }

  // OSM tiles under the grid: Web Mercator tile numbers of the view's corners about the origin.
  function drawTiles(ctx, v, origin, redraw) {
    if (!origin || typeof navigator === "undefined" || !navigator.onLine) return false;
    const [lat0, lon0] = origin;
    const rad = Math.PI / 180;
    const mPerDegLat = EARTH_R * rad, mPerDegLon = EARTH_R * rad * Math.cos(lat0 * rad);
    const metresPerPx = 1 / v.scale;
    const z = Math.max(1, Math.min(19, Math.round(Math.log2(156543.03 * Math.cos(lat0 * rad) / metresPerPx))));
    const n = Math.pow(2, z);
    const lonOf = x => lon0 + x / mPerDegLon, latOf = y => lat0 + y / mPerDegLat;
    const tileX = lon => (lon + 180) / 360 * n;
    const tileY = lat => (1 - Math.log(Math.tan(lat * rad) + 1 / Math.cos(lat * rad)) / Math.PI) / 2 * n;
    const lonT = tx => tx / n * 360 - 180;
    const latT = ty => Math.atan(Math.sinh(Math.PI * (1 - 2 * ty / n))) / rad;
    const west = v.cx - v.width / 2 / v.scale, east = v.cx + v.width / 2 / v.scale;
    const south = v.cy - v.height / 2 / v.scale, north = v.cy + v.height / 2 / v.scale;
    const tx0 = Math.floor(tileX(lonOf(west))), tx1 = Math.floor(tileX(lonOf(east)));
    const ty0 = Math.floor(tileY(latOf(north))), ty1 = Math.floor(tileY(latOf(south)));
    if ((tx1 - tx0 + 1) * (ty1 - ty0 + 1) > 64) return false;
    let drew = false;
    for (let tx = tx0; tx <= tx1; tx++) {
      for (let ty = ty0; ty <= ty1; ty++) {
        const url = TILE_URL.replace("{z}", z).replace("{x}", tx).replace("{y}", ty);
        let img = tileCache.get(url);
        if (!img) {
          img = new Image();
          img.crossOrigin = "anonymous";
          img.onload = () => redraw && redraw();
          img.onerror = () => { img.failed = true; };  // offline or refused: the grid is enough
          img.src = url;
          tileCache.set(url, img);
        }
        if (!img.complete || img.failed || !img.naturalWidth) continue;
        const xw = (lonT(tx) - lon0) * mPerDegLon, xe = (lonT(tx + 1) - lon0) * mPerDegLon;
        const yn = (latT(ty) - lat0) * mPerDegLat, ys = (latT(ty + 1) - lat0) * mPerDegLat;
        const [px0, py0] = toPx(v, xw, yn), [px1, py1] = toPx(v, xe, ys);
        ctx.globalAlpha = 0.8;
        ctx.drawImage(img, px0, py0, px1 - px0, py1 - py0);
        ctx.globalAlpha = 1;
        drew = true;
      }
    }
    return drew;
  }

  // Draw everything. data: {origin, path: [[t, x, y, sigma]], fixes: [[t, x, y, acc]]};
  // opts: {colors: per path point, upto: last path index drawn, tiles: bool, redraw: fn,
  //        provisionalFrom: time (s) after which the path is drawn dashed (the live path's provisional end)}.
  function draw(canvas, data, opts = {}) {
    const ratio = window.devicePixelRatio || 1;
    const w = canvas.clientWidth || 800, h = canvas.clientHeight || 600;
    if (canvas.width !== Math.round(w * ratio)) { canvas.width = Math.round(w * ratio); canvas.height = Math.round(h * ratio); }
    const ctx = canvas.getContext("2d");
    ctx.setTransform(ratio, 0, 0, ratio, 0, 0);
    ctx.fillStyle = "#f7f9fb";
    ctx.fillRect(0, 0, w, h);
    const path = data.path || [], fixes = data.fixes || [];
    const upto = opts.upto === undefined ? path.length - 1 : opts.upto;
    const goodFixes = fixes.filter(f => f[3] === null || f[3] < 100);
    const v = fitView(path.map(p => [p[1], p[2]]).concat(goodFixes.map(f => [f[1], f[2]])), w, h);
    const tiles = opts.tiles !== false && drawTiles(ctx, v, data.origin, opts.redraw);
    drawGrid(ctx, v, tiles);
    // the floor plan under everything (issue 36): data.plan = [plan: [polygon: [ring: [[x, y], ...]]]],
    // outer ring filled grey-blue, holes (obstacles) cut out with the even-odd rule
    ctx.fillStyle = "rgba(120,140,170,0.22)"; ctx.strokeStyle = "rgba(90,100,120,0.5)"; ctx.lineWidth = 0.7;
    for (const plan of data.plan || []) {
      for (const poly of plan) {
        ctx.beginPath();
        for (const ring of poly) {
          ring.forEach(([x, y], i) => { const [px, py] = toPx(v, x, y); if (i) ctx.lineTo(px, py); else ctx.moveTo(px, py); });
          ctx.closePath();
        }
        ctx.fill("evenodd"); ctx.stroke();
      }
    }
    for (const [, x, y, acc] of goodFixes) {  // fixes: accuracy circle and centre
      const [px, py] = toPx(v, x, y);
      ctx.fillStyle = "rgba(214,39,40,0.05)"; ctx.strokeStyle = "rgba(214,39,40,0.25)"; ctx.lineWidth = 1;
      if (acc !== null) { ctx.beginPath(); ctx.arc(px, py, Math.max(1, acc * v.scale), 0, 2 * Math.PI); ctx.fill(); ctx.stroke(); }
      ctx.fillStyle = "rgba(214,39,40,0.8)";
      ctx.beginPath(); ctx.arc(px, py, 2, 0, 2 * Math.PI); ctx.fill();
    }
    ctx.lineWidth = 3; ctx.lineCap = "round"; ctx.lineJoin = "round";
    const provisional = opts.provisionalFrom === undefined || opts.provisionalFrom === null ? Infinity : opts.provisionalFrom;
    for (let i = 1; i <= upto && i < path.length; i++) {
      const [ax, ay] = toPx(v, path[i - 1][1], path[i - 1][2]), [bx, by] = toPx(v, path[i][1], path[i][2]);
      ctx.strokeStyle = (opts.colors && opts.colors[i]) || "#1f77b4";
      ctx.setLineDash(path[i][0] > provisional ? [6, 5] : []);  // dashed: still being revised
      ctx.beginPath(); ctx.moveTo(ax, ay); ctx.lineTo(bx, by); ctx.stroke();
    }
    ctx.setLineDash([]);
    if (path.length && upto >= 0) {
      const [sx, sy] = toPx(v, path[0][1], path[0][2]);
      ctx.fillStyle = "#2ca02c"; ctx.beginPath(); ctx.arc(sx, sy, 6, 0, 2 * Math.PI); ctx.fill();
      const p = path[Math.min(upto, path.length - 1)];
      const [ex, ey] = toPx(v, p[1], p[2]);
      if (p[3] !== null && p[3] !== undefined) {  // the path's 1-σ where the smoother gives one
        ctx.strokeStyle = "rgba(31,119,180,0.5)"; ctx.lineWidth = 1;
        ctx.beginPath(); ctx.arc(ex, ey, Math.max(3, p[3] * v.scale), 0, 2 * Math.PI); ctx.stroke();
      }
      ctx.fillStyle = "#111"; ctx.beginPath(); ctx.arc(ex, ey, 5, 0, 2 * Math.PI); ctx.fill();
    }
    return {tiles, scale: v.scale};
  }

  const PALETTE = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f"];
  const KNOWN = {walking: "#1f77b4", jogging: "#ff7f0e", upstairs: "#2ca02c", downstairs: "#9467bd",
                 standing: "#7f7f7f", sitting: "#8c564b"};
  function activityColor(label) {
    if (!label) return "#1f77b4";
    if (KNOWN[label]) return KNOWN[label];
    let h = 0;
    for (const c of label) h = (h * 31 + c.charCodeAt(0)) >>> 0;
    return PALETTE[h % PALETTE.length];
  }

  return {draw, activityColor, niceStep};
})();
