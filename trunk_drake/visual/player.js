// trunk-drake: moves the muscle lines of a Meshcat recording and colours them by activation.
// Meshcat's animation moves the bone segments; a muscle's path sites move with their segment,
// its wrap points (tangent points and arcs on the wrapping surfaces) come frame by frame from
// the embedded data. Data: the JSON in <script id="trunk-drake-player"> (see visual/page.py).
(function () {
  "use strict";
  const data = JSON.parse(document.getElementById("trunk-drake-player").textContent);
  const bytes = (b64) => Uint8Array.from(atob(b64), (c) => c.charCodeAt(0));
  const wrap = new Int16Array(bytes(data.wrap.data).buffer);
  const activation = bytes(data.activation.data);
  const nFrames = data.frames, nMuscles = data.muscles.length, nWrap = data.wrap.points;
  const lines = new Array(nMuscles).fill(null);
  const segments = data.segments.map((path) => viewer.scene_tree.find(path));
  const matrix = new MeshCat.THREE.Matrix4();
  let shownTime = null, shownLines = 0;

  function colour(a) {  // activation / scale in [0, 1] -> blue, yellow, red
    const stops = data.colours;
    const x = Math.min(Math.max(a, 0), 1) * (stops.length - 1);
    const i = Math.min(Math.floor(x), stops.length - 2), w = x - i;
    return stops[i].map((c, k) => c + w * (stops[i + 1][k] - c));
  }

  function findLines() {
    let found = 0;
    for (let m = 0; m < nMuscles; m++) {
      if (lines[m] === null) {
        const object = viewer.scene_tree.find(data.muscles[m].concat(["<object>"])).object;
        if (object && object.isLine &&
            object.geometry.attributes.position.count === data.vertices[m].length) {
          object.frustumCulled = false;
          lines[m] = object;
        }
      }
      if (lines[m] !== null) found++;
    }
    return found;
  }

  function update() {
    const time = viewer.animator.time || 0;
    const found = shownLines < nMuscles ? findLines() : nMuscles;
    window.trunkDrakeReady = found === nMuscles && viewer.animator.duration > 0;  // for tests and scripts
    if (time === shownTime && found === shownLines) return;
    shownTime = time;
    shownLines = found;
    const f = Math.min(Math.max(time * data.fps, 0), nFrames - 1);
    const k0 = Math.floor(f), k1 = Math.min(k0 + 1, nFrames - 1), w = f - k0;
    const e = segments.map((node) => {
      const o = node.object;
      return matrix.compose(o.position, o.quaternion, o.scale).elements.slice();
    });
    const off = data.wrap.offset, s = data.wrap.scale;
    for (let m = 0; m < nMuscles; m++) {
      const line = lines[m];
      if (line === null) continue;
      const out = line.geometry.attributes.position.array;
      data.vertices[m].forEach((v, j) => {
        if (v[0] >= 0) {
          const x = v[1], y = v[2], z = v[3], t = e[v[0]];
          out[3 * j] = t[0] * x + t[4] * y + t[8] * z + t[12];
          out[3 * j + 1] = t[1] * x + t[5] * y + t[9] * z + t[13];
          out[3 * j + 2] = t[2] * x + t[6] * y + t[10] * z + t[14];
        } else {
          const a = 3 * (k0 * nWrap + v[1]), b = 3 * (k1 * nWrap + v[1]);
          for (let c = 0; c < 3; c++) out[3 * j + c] = off[c] + s * ((1 - w) * wrap[a + c] + w * wrap[b + c]);
        }
      });
      line.geometry.attributes.position.needsUpdate = true;
      const act = ((1 - w) * activation[k0 * nMuscles + m] + w * activation[k1 * nMuscles + m]) / 255;
      line.material.color.setRGB(...colour(act), MeshCat.THREE.SRGBColorSpace);
    }
    viewer.set_dirty();
  }

  viewer.animate = function () {
    viewer.animator.update();
    update();
    if (viewer.needs_render) viewer.render();
  };
})();
