// The prt report viewer: HDR image comparison (A/B flip and wipe, exposure, tone curves,
// false-colour errors, zoom and pan with nearest-neighbour pixels, a pixel probe of every
// method), interactive charts and sortable tables. Hand-written, no dependencies, works from
// file://. The page embeds two JSON blocks, #prt-report (report.json) and #prt-images (the
// images' names and size), and each image's linear RGB as base64 little-endian f16 in its own
// element, #prt-image-N, decoded when first shown.
(function () {
  'use strict';

  const report = JSON.parse(document.getElementById('prt-report').textContent);
  const imageBlock = JSON.parse(document.getElementById('prt-images').textContent);
  const W = imageBlock.width;
  const H = imageBlock.height;
  const images = imageBlock.images;

  // ---------------------------------------------------------------- f16 decoding
  const HALF = new Float32Array(65536);
  (function fillHalfTable() {
    for (let h = 0; h < 65536; h++) {
      const s = h & 0x8000 ? -1 : 1;
      const e = (h >> 10) & 0x1f;
      const m = h & 0x3ff;
      let v;
      if (e === 0) v = m * Math.pow(2, -24);
      else if (e === 31) v = m ? NaN : Infinity;
      else v = (1 + m / 1024) * Math.pow(2, e - 15);
      HALF[h] = s * v;
    }
  })();
  const decoded = new Map();
  function pixels(i) {
    let f = decoded.get(i);
    if (f) return f;
    const bin = atob(document.getElementById('prt-image-' + i).textContent.trim());
    const n = bin.length >> 1;
    f = new Float32Array(n);
    for (let k = 0; k < n; k++) {
      f[k] = HALF[bin.charCodeAt(2 * k) | (bin.charCodeAt(2 * k + 1) << 8)];
    }
    decoded.set(i, f);
    return f;
  }

  // ---------------------------------------------------------------- tone curves
  function srgbOetf(x) {
    x = x <= 0 ? 0 : x >= 1 ? 1 : x;
    return x <= 0.0031308 ? 12.92 * x : 1.055 * Math.pow(x, 1 / 2.4) - 0.055;
  }
  const TONES = {
    srgb: { label: 'sRGB, clipped', f: (x) => srgbOetf(x) },
    aces: {
      label: 'ACES filmic (Narkowicz fit)',
      f: (x) => srgbOetf(x <= 0 ? 0 : (x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14)),
    },
    reinhard: { label: 'Reinhard x/(1+x)', f: (x) => srgbOetf(x <= 0 ? 0 : x / (1 + x)) },
    gamma: { label: 'gamma 2.2, clipped', f: (x) => Math.pow(x <= 0 ? 0 : x >= 1 ? 1 : x, 1 / 2.2) },
    linear: { label: 'linear, clipped (no curve)', f: (x) => (x <= 0 ? 0 : x >= 1 ? 1 : x) },
  };

  // A perceptually ordered false-colour map (viridis, 9 stops, linear between them).
  const VIRIDIS = [
    [68, 1, 84], [71, 44, 122], [59, 81, 139], [44, 113, 142], [33, 144, 141],
    [39, 173, 129], [92, 200, 99], [170, 220, 50], [253, 231, 37],
  ];
  function falseColour(t, out, o) {
    t = t <= 0 ? 0 : t >= 1 ? 1 : t;
    const x = t * (VIRIDIS.length - 1);
    const i = Math.min(Math.floor(x), VIRIDIS.length - 2);
    const a = x - i;
    for (let c = 0; c < 3; c++) out[o + c] = VIRIDIS[i][c] * (1 - a) + VIRIDIS[i + 1][c] * a;
  }
  const lum = (p, k) => 0.2126 * p[k] + 0.7152 * p[k + 1] + 0.0722 * p[k + 2];

  // ---------------------------------------------------------------- state and controls
  const $ = (id) => document.getElementById(id);
  const state = {
    a: 0,
    b: Math.min(1, images.length - 1),
    mode: 'a',
    showB: false,
    ev: 0,
    tone: 'srgb',
    wipe: 0.5,
    scale: 'auto',
    zoom: 1,
    panX: 0,
    panY: 0,
  };
  function option(select, value, text) {
    const o = document.createElement('option');
    o.value = value;
    o.textContent = text;
    select.appendChild(o);
  }
  for (const id of ['pick-a', 'pick-b']) {
    const sel = $(id);
    images.forEach((im, i) => option(sel, String(i), im.label));
  }
  $('pick-a').value = String(state.a);
  $('pick-b').value = String(state.b);
  for (const [k, t] of Object.entries(TONES)) option($('tone'), k, t.label);

  const canvas = $('view');
  const ctx = canvas.getContext('2d');
  const buffer = document.createElement('canvas');
  buffer.width = W;
  buffer.height = H;
  const bctx = buffer.getContext('2d');
  const frame = bctx.createImageData(W, H);

  // The error picture's scale: fixed, or the 99th percentile of the error (auto).
  let legend = { max: 1, label: '' };
  function errorValues(kind) {
    const pa = pixels(state.a);
    const pb = pixels(state.b);
    const v = new Float32Array(W * H);
    for (let p = 0, k = 0; p < W * H; p++, k += 3) {
      const d = Math.abs(lum(pa, k) - lum(pb, k));
      v[p] = kind === 'rel' ? d / Math.max(Math.abs(lum(pb, k)), 1e-3) : d;
    }
    return v;
  }
  function percentile(values, q) {
    const finite = Array.from(values).filter((x) => Number.isFinite(x));
    if (finite.length === 0) return 1;
    finite.sort((x, y) => x - y);
    return finite[Math.min(finite.length - 1, Math.floor(q * finite.length))] || 1e-6;
  }

  function render() {
    const out = frame.data;
    if (state.mode === 'diff' || state.mode === 'rel') {
      const v = errorValues(state.mode);
      const max = state.scale === 'auto' ? percentile(v, 0.99) : Number(state.scale);
      legend = {
        max,
        label:
          state.mode === 'rel'
            ? '|Y(A) − Y(B)| / max(Y(B), 0.001), luminance'
            : '|Y(A) − Y(B)|, luminance, linear radiance',
      };
      for (let p = 0; p < W * H; p++) {
        falseColour(v[p] / max, out, 4 * p);
        out[4 * p + 3] = 255;
      }
    } else {
      const scale = Math.pow(2, state.ev);
      const tone = TONES[state.tone].f;
      const pa = pixels(state.a);
      const pb = pixels(state.b);
      const split = Math.round(state.wipe * W);
      for (let y = 0; y < H; y++) {
        for (let x = 0; x < W; x++) {
          let src;
          if (state.mode === 'wipe') src = x < split ? pa : pb;
          else if (state.mode === 'b' || (state.mode === 'flip' && state.showB)) src = pb;
          else src = pa;
          const p = y * W + x;
          for (let c = 0; c < 3; c++) out[4 * p + c] = 255 * tone(scale * src[3 * p + c]) + 0.5;
          out[4 * p + 3] = 255;
        }
      }
      if (state.mode === 'wipe') {
        for (let y = 0; y < H; y++) {
          const p = 4 * (y * W + Math.min(split, W - 1));
          out[p] = 255;
          out[p + 1] = 64;
          out[p + 2] = 64;
        }
      }
    }
    bctx.putImageData(frame, 0, 0);
    draw();
    updateLegend();
    updateCaption();
  }

  function fit() {
    const box = canvas.parentElement.getBoundingClientRect();
    canvas.width = Math.max(1, Math.floor(box.width));
    canvas.height = Math.max(1, Math.floor(Math.min(box.width * (H / W), window.innerHeight * 0.7)));
    state.zoom = Math.min(canvas.width / W, canvas.height / H);
    state.panX = (canvas.width - W * state.zoom) / 2;
    state.panY = (canvas.height - H * state.zoom) / 2;
    draw();
  }
  function draw() {
    ctx.setTransform(1, 0, 0, 1, 0, 0);
    ctx.fillStyle = '#222';
    ctx.fillRect(0, 0, canvas.width, canvas.height);
    ctx.imageSmoothingEnabled = false;
    ctx.setTransform(state.zoom, 0, 0, state.zoom, state.panX, state.panY);
    ctx.drawImage(buffer, 0, 0);
    ctx.setTransform(1, 0, 0, 1, 0, 0);
    $('zoom-level').textContent = (100 * state.zoom).toFixed(0) + ' %';
  }
  function updateLegend() {
    const show = state.mode === 'diff' || state.mode === 'rel';
    $('legend').hidden = !show;
    if (!show) return;
    const bar = $('legend-bar');
    if (!bar.dataset.filled) {
      const c = bar.getContext('2d');
      const img = c.createImageData(bar.width, 1);
      for (let x = 0; x < bar.width; x++) {
        falseColour(x / (bar.width - 1), img.data, 4 * x);
        img.data[4 * x + 3] = 255;
      }
      for (let y = 0; y < bar.height; y++) c.putImageData(img, 0, y);
      bar.dataset.filled = '1';
    }
    $('legend-min').textContent = '0';
    $('legend-max').textContent = legend.max.toPrecision(3) + (state.scale === 'auto' ? ' (99th percentile)' : '');
    $('legend-label').textContent = legend.label;
  }
  function updateCaption() {
    const a = images[state.a].label;
    const b = images[state.b].label;
    const text = {
      a: 'A: ' + a,
      b: 'B: ' + b,
      flip: (state.showB ? 'B: ' + b : 'A: ' + a) + '  (press F or the button to flip)',
      wipe: 'left A: ' + a + ' | right B: ' + b,
      diff: '|A − B|: ' + a + ' against ' + b,
      rel: 'relative |A − B| / B: ' + a + ' against ' + b,
    }[state.mode];
    $('caption').textContent = text;
  }

  // Pixel probe: every image's linear RGB at the pixel under the cursor.
  function probe(ev) {
    const r = canvas.getBoundingClientRect();
    const cx = ((ev.clientX - r.left) * canvas.width) / r.width;
    const cy = ((ev.clientY - r.top) * canvas.height) / r.height;
    const x = Math.floor((cx - state.panX) / state.zoom);
    const y = Math.floor((cy - state.panY) / state.zoom);
    if (x < 0 || y < 0 || x >= W || y >= H) return;
    $('probe-xy').textContent = 'pixel (' + x + ', ' + y + ')';
    const body = $('probe-body');
    body.textContent = '';
    images.forEach((im, i) => {
      const p = pixels(i);
      const k = 3 * (y * W + x);
      const tr = document.createElement('tr');
      if (i === state.a) tr.className = 'is-a';
      if (i === state.b) tr.className = 'is-b';
      const cells = [
        (i === state.a ? 'A ' : i === state.b ? 'B ' : '') + im.label,
        p[k].toPrecision(4),
        p[k + 1].toPrecision(4),
        p[k + 2].toPrecision(4),
      ];
      for (const c of cells) {
        const td = document.createElement('td');
        td.textContent = c;
        tr.appendChild(td);
      }
      body.appendChild(tr);
    });
  }

  // Zoom about the cursor, drag to pan.
  canvas.addEventListener('wheel', (ev) => {
    ev.preventDefault();
    const r = canvas.getBoundingClientRect();
    const cx = ((ev.clientX - r.left) * canvas.width) / r.width;
    const cy = ((ev.clientY - r.top) * canvas.height) / r.height;
    const f = ev.deltaY < 0 ? 1.25 : 0.8;
    const z = Math.min(64, Math.max(0.1, state.zoom * f));
    state.panX = cx - ((cx - state.panX) * z) / state.zoom;
    state.panY = cy - ((cy - state.panY) * z) / state.zoom;
    state.zoom = z;
    draw();
  }, { passive: false });
  let drag = null;
  canvas.addEventListener('mousedown', (ev) => {
    drag = { x: ev.clientX, y: ev.clientY, px: state.panX, py: state.panY };
  });
  window.addEventListener('mouseup', () => { drag = null; });
  canvas.addEventListener('mousemove', (ev) => {
    if (drag) {
      const r = canvas.getBoundingClientRect();
      state.panX = drag.px + ((ev.clientX - drag.x) * canvas.width) / r.width;
      state.panY = drag.py + ((ev.clientY - drag.y) * canvas.height) / r.height;
      draw();
    }
    probe(ev);
  });

  const set = (key, value) => {
    state[key] = value;
    render();
  };
  $('pick-a').addEventListener('change', (e) => set('a', Number(e.target.value)));
  $('pick-b').addEventListener('change', (e) => set('b', Number(e.target.value)));
  $('mode').addEventListener('change', (e) => set('mode', e.target.value));
  $('tone').addEventListener('change', (e) => set('tone', e.target.value));
  $('ev').addEventListener('input', (e) => {
    $('ev-value').textContent = Number(e.target.value).toFixed(1) + ' EV';
    set('ev', Number(e.target.value));
  });
  $('wipe').addEventListener('input', (e) => set('wipe', Number(e.target.value)));
  $('scale').addEventListener('change', (e) => {
    const v = e.target.value.trim();
    set('scale', v === '' || !(Number(v) > 0) ? 'auto' : v);
  });
  $('flip').addEventListener('click', () => {
    if (state.mode !== 'flip') $('mode').value = state.mode = 'flip';
    state.showB = !state.showB;
    render();
  });
  $('swap').addEventListener('click', () => {
    [state.a, state.b] = [state.b, state.a];
    $('pick-a').value = String(state.a);
    $('pick-b').value = String(state.b);
    render();
  });
  $('fit').addEventListener('click', fit);
  window.addEventListener('keydown', (ev) => {
    if (ev.target.tagName === 'INPUT' || ev.target.tagName === 'SELECT') return;
    if (ev.key === 'f' || ev.key === 'F') $('flip').click();
  });
  window.addEventListener('resize', fit);

  // ---------------------------------------------------------------- charts (SVG)
  const SVG = 'http://www.w3.org/2000/svg';
  function el(name, attrs, parent) {
    const e = document.createElementNS(SVG, name);
    for (const [k, v] of Object.entries(attrs)) e.setAttribute(k, v);
    if (parent) parent.appendChild(e);
    return e;
  }
  const tip = $('tooltip');
  function showTip(ev, html) {
    tip.hidden = false;
    tip.textContent = '';
    for (const line of html) {
      const d = document.createElement('div');
      d.textContent = line;
      tip.appendChild(d);
    }
    tip.style.left = ev.pageX + 12 + 'px';
    tip.style.top = ev.pageY + 12 + 'px';
  }
  const hideTip = () => { tip.hidden = true; };
  const COLOURS = ['#1f77b4', '#d62728', '#2ca02c', '#9467bd', '#ff7f0e', '#8c564b', '#17becf'];

  // A line/scatter chart: series of {name, points: [{x, y, row}]}; hover shows the row.
  function chart(container, opts) {
    const w = 560, h = 300, m = { l: 56, r: 12, t: 24, b: 40 };
    const svg = el('svg', { viewBox: `0 0 ${w} ${h}`, class: 'chart', role: 'img' }, container);
    el('text', { x: w / 2, y: 16, 'text-anchor': 'middle', class: 'title' }, svg).textContent = opts.title;
    const all = opts.series.flatMap((s) => s.points).filter((p) => Number.isFinite(p.x) && Number.isFinite(p.y));
    if (all.length === 0) return;
    const tx = opts.logX ? Math.log10 : (v) => v;
    let [x0, x1] = [Math.min(...all.map((p) => tx(p.x))), Math.max(...all.map((p) => tx(p.x)))];
    let [y0, y1] = [Math.min(...all.map((p) => p.y)), Math.max(...all.map((p) => p.y))];
    if (x1 === x0) { x0 -= 1; x1 += 1; }
    if (y1 === y0) { y0 -= 1; y1 += 1; }
    const padY = 0.05 * (y1 - y0);
    y0 = y0 >= 0 && y0 - padY < 0 ? 0 : y0 - padY;
    y1 += padY;
    const X = (v) => m.l + ((tx(v) - x0) / (x1 - x0)) * (w - m.l - m.r);
    const Y = (v) => h - m.b - ((v - y0) / (y1 - y0)) * (h - m.t - m.b);
    el('line', { x1: m.l, y1: h - m.b, x2: w - m.r, y2: h - m.b, class: 'axis' }, svg);
    el('line', { x1: m.l, y1: m.t, x2: m.l, y2: h - m.b, class: 'axis' }, svg);
    for (let i = 0; i <= 4; i++) {
      const yv = y0 + (i / 4) * (y1 - y0);
      el('text', { x: m.l - 4, y: Y(yv) + 4, 'text-anchor': 'end', class: 'tick' }, svg).textContent = yv.toPrecision(3);
      if (!opts.integerX) {
        const xv = x0 + (i / 4) * (x1 - x0);
        const label = opts.logX ? Math.pow(10, xv) : xv;
        el('text', { x: m.l + (i / 4) * (w - m.l - m.r), y: h - m.b + 14, 'text-anchor': 'middle', class: 'tick' }, svg).textContent = Number(label.toPrecision(3)).toString();
      }
    }
    if (opts.integerX) {
      for (let v = Math.ceil(x0); v <= x1; v++) {
        el('text', { x: X(v), y: h - m.b + 14, 'text-anchor': 'middle', class: 'tick' }, svg).textContent = String(v);
      }
    }
    el('text', { x: (m.l + w - m.r) / 2, y: h - 6, 'text-anchor': 'middle', class: 'label' }, svg).textContent = opts.xLabel;
    el('text', { x: 12, y: (m.t + h - m.b) / 2, transform: `rotate(-90 12 ${(m.t + h - m.b) / 2})`, 'text-anchor': 'middle', class: 'label' }, svg).textContent = opts.yLabel;
    opts.series.forEach((s, si) => {
      const colour = COLOURS[si % COLOURS.length];
      const pts = s.points.filter((p) => Number.isFinite(p.x) && Number.isFinite(p.y));
      if (pts.length > 1 && !opts.noLines) {
        el('polyline', { points: pts.map((p) => `${X(p.x)},${Y(p.y)}`).join(' '), fill: 'none', stroke: colour, 'stroke-width': 1.5 }, svg);
      }
      for (const p of pts) {
        const c = el('circle', { cx: X(p.x), cy: Y(p.y), r: 4, fill: colour, class: 'point' }, svg);
        c.addEventListener('mousemove', (ev) => showTip(ev, [s.name].concat(p.tip)));
        c.addEventListener('mouseleave', hideTip);
      }
      el('text', { x: w - m.r - 4, y: m.t + 14 * (si + 1), 'text-anchor': 'end', fill: colour, class: 'legend' }, svg).textContent = s.name;
    });
  }

  function rowTip(r) {
    return [
      'order ' + r.order + ' (' + r.coefficients + ' coefficients)',
      'full: ' + r.full_ms.toFixed(3) + ' ms, PSNR ' + fmt(r.psnr_full_vs_reference) + ' dB',
      'adaptive: ' + r.adaptive_ms.toFixed(3) + ' ms, PSNR ' + fmt(r.psnr_adaptive_vs_reference) + ' dB',
      'speed-up ' + r.speedup.toFixed(2) + '×, threshold ' + nice(report.settings.threshold),
    ];
  }
  function nice(v) {
    return typeof v === 'number' && !Number.isInteger(v) ? String(Number(v.toPrecision(6))) : String(v);
  }
  function fmt(v) {
    return typeof v === 'number' && Number.isFinite(v) ? v.toFixed(2) : '∞';
  }
  const orders = report.orders || [];
  const charts = $('charts');
  chart(charts, {
    title: 'PSNR against the path-traced reference, per order', integerX: true,
    xLabel: 'SH order (bands)', yLabel: 'PSNR, dB (8-bit view, object pixels)',
    series: [
      { name: 'full SH', points: orders.map((r) => ({ x: r.order, y: r.psnr_full_vs_reference, tip: rowTip(r) })) },
      { name: 'adaptive SH', points: orders.map((r) => ({ x: r.order, y: r.psnr_adaptive_vs_reference, tip: rowTip(r) })) },
    ],
  });
  chart(charts, {
    title: 'Error against time (one frame; hover for the order)', logX: true, noLines: true,
    xLabel: 'shading time, ms (log)', yLabel: 'PSNR against the reference, dB',
    series: [
      { name: 'full SH', points: orders.map((r) => ({ x: r.full_ms, y: r.psnr_full_vs_reference, tip: rowTip(r) })) },
      { name: 'adaptive SH', points: orders.map((r) => ({ x: r.adaptive_ms, y: r.psnr_adaptive_vs_reference, tip: rowTip(r) })) },
    ],
  });
  if (orders.some((r) => r.roi_diffuse !== null && r.roi_diffuse !== undefined)) {
    chart(charts, {
      title: 'Adaptive SH: region of interest per order', integerX: true,
      xLabel: 'SH order (bands)', yLabel: 'points in the ROI, %',
      series: [
        { name: 'diffuse ROI', points: orders.map((r) => ({ x: r.order, y: 100 * (r.roi_diffuse ?? NaN), tip: rowTip(r) })) },
        { name: 'specular ROI', points: orders.map((r) => ({ x: r.order, y: 100 * (r.roi_specular ?? NaN), tip: rowTip(r) })) },
      ],
    });
  }
  budgetChart(charts, report.error_budget || []);

  // The error budget: per order, a stacked bar of each term's share of the total MSE.
  function budgetChart(container, rows) {
    if (rows.length === 0) return;
    const names = Object.keys(rows[0].terms);
    const w = 560, h = 300, m = { l: 56, r: 130, t: 24, b: 40 };
    const svg = el('svg', { viewBox: `0 0 ${w} ${h}`, class: 'chart', role: 'img' }, container);
    el('text', { x: w / 2, y: 16, 'text-anchor': 'middle', class: 'title' }, svg).textContent = 'Error budget: share of the MSE against the reference';
    const bw = (w - m.l - m.r) / rows.length;
    const Y = (v) => h - m.b - v * (h - m.t - m.b);
    el('line', { x1: m.l, y1: h - m.b, x2: w - m.r, y2: h - m.b, class: 'axis' }, svg);
    el('line', { x1: m.l, y1: m.t, x2: m.l, y2: h - m.b, class: 'axis' }, svg);
    for (let i = 0; i <= 4; i++) {
      el('text', { x: m.l - 4, y: Y(i / 4) + 4, 'text-anchor': 'end', class: 'tick' }, svg).textContent = 25 * i + ' %';
    }
    el('text', { x: (m.l + w - m.r) / 2, y: h - 6, 'text-anchor': 'middle', class: 'label' }, svg).textContent = 'SH order';
    rows.forEach((r, ri) => {
      const total = names.reduce((s, n) => s + Math.max(0, Number(r.terms[n]) || 0), 0) || 1;
      let acc = 0;
      names.forEach((n, ni) => {
        const v = Math.max(0, Number(r.terms[n]) || 0) / total;
        const rect = el('rect', { x: m.l + ri * bw + 1, y: Y(acc + v), width: Math.max(1, bw - 2), height: Math.max(0, Y(acc) - Y(acc + v)), fill: COLOURS[ni % COLOURS.length], class: 'bar' }, svg);
        rect.addEventListener('mousemove', (ev) => showTip(ev, [
          'order ' + r.order + ': ' + n,
          'MSE ' + Number(r.terms[n]).toExponential(3) + ' (' + (100 * v).toFixed(1) + ' % of ' + r.total_mse.toExponential(3) + ')',
          'largest term: ' + r.largest,
        ]));
        rect.addEventListener('mouseleave', hideTip);
        acc += v;
      });
      el('text', { x: m.l + (ri + 0.5) * bw, y: h - m.b + 14, 'text-anchor': 'middle', class: 'tick' }, svg).textContent = r.order;
    });
    names.forEach((n, ni) => {
      el('rect', { x: w - m.r + 8, y: m.t + 14 * ni, width: 10, height: 10, fill: COLOURS[ni % COLOURS.length] }, svg);
      el('text', { x: w - m.r + 22, y: m.t + 14 * ni + 9, class: 'legend' }, svg).textContent = n;
    });
  }

  // ---------------------------------------------------------------- settings, load
  const dl = $('settings');
  for (const [k, v] of Object.entries(report.settings || {})) {
    const dt = document.createElement('dt');
    dt.textContent = k.replace(/_/g, ' ');
    const dd = document.createElement('dd');
    dd.textContent = typeof v === 'object' && v !== null ? JSON.stringify(v) : nice(v);
    dl.appendChild(dt);
    dl.appendChild(dd);
  }

  // ---------------------------------------------------------------- sortable tables
  function cellValue(td) {
    const t = td.textContent.trim().replace(/[×%]/g, '');
    if (t === '∞') return Infinity;
    const n = parseFloat(t);
    return Number.isFinite(n) && /^[-+]?[\d.]/.test(t) ? n : t.toLowerCase();
  }
  for (const table of document.querySelectorAll('table.sortable')) {
    const heads = table.querySelectorAll('tr:first-child th');
    heads.forEach((th, col) => {
      th.title = 'sort by this column';
      th.addEventListener('click', () => {
        const rows = Array.from(table.querySelectorAll('tr')).slice(1);
        const asc = th.dataset.sort !== 'asc';
        heads.forEach((h) => { delete h.dataset.sort; });
        th.dataset.sort = asc ? 'asc' : 'desc';
        rows.sort((r1, r2) => {
          const a = cellValue(r1.children[col]);
          const b = cellValue(r2.children[col]);
          const c = typeof a === 'number' && typeof b === 'number' ? a - b : String(a).localeCompare(String(b));
          return asc ? c : -c;
        });
        for (const r of rows) table.appendChild(r);
      });
    });
  }

  fit();
  render();
  $('ev-value').textContent = '0.0 EV';
  // For tests and scripts: the state, and a checksum of the displayed pixels.
  window.prtViewer = {
    ready: true,
    state,
    images: images.map((im) => im.label),
    checksum() {
      const d = ctx.getImageData(0, 0, canvas.width, canvas.height).data;
      let h = 2166136261;
      for (let i = 0; i < d.length; i += 7) h = Math.imul(h ^ d[i], 16777619) >>> 0;
      return h;
    },
  };
})();
