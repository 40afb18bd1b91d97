// A unit UV sphere (positions = normals) as a GLB with one metallic-roughness material (white:
// base colour 1) of the given roughness and metallic factors; with `camera`, also an
// orthographic camera at (0, 0, 1000) looking down −Z that frames the sphere (xmag = ymag = 1).
// For the render pages (filament_render.html, gltf_viewer_render.html).
function sphereGlb(roughness, metallic, camera) {
  const rings = 128, segs = 256, pos = [], idx = [];
  for (let i = 0; i <= rings; ++i) {
    const th = Math.PI * i / rings;
    for (let j = 0; j <= segs; ++j) {
      const ph = 2 * Math.PI * j / segs;
      pos.push(Math.sin(th) * Math.cos(ph), Math.cos(th), -Math.sin(th) * Math.sin(ph));
    }
  }
  for (let i = 0; i < rings; ++i)
    for (let j = 0; j < segs; ++j) {
      const a = i * (segs + 1) + j, b = a + segs + 1;
      idx.push(a, b, a + 1, a + 1, b, b + 1);
    }
  const p = new Float32Array(pos), ix = new Uint32Array(idx);
  const bin = new Uint8Array(2 * p.byteLength + ix.byteLength);
  bin.set(new Uint8Array(p.buffer), 0);
  bin.set(new Uint8Array(p.buffer), p.byteLength);
  bin.set(new Uint8Array(ix.buffer), 2 * p.byteLength);
  const n = p.length / 3;
  const json = JSON.stringify({
    asset: { version: '2.0' }, scene: 0, scenes: [{ nodes: camera ? [0, 1] : [0] }],
    nodes: [{ mesh: 0 }, { camera: 0, translation: [0, 0, 1000] }],
    cameras: [{ type: 'orthographic', orthographic: { xmag: 1, ymag: 1, znear: 990, zfar: 1010 } }],
    meshes: [{ primitives: [{ attributes: { POSITION: 0, NORMAL: 1 }, indices: 2, material: 0 }] }],
    materials: [{ pbrMetallicRoughness: { baseColorFactor: [1, 1, 1, 1], metallicFactor: metallic, roughnessFactor: roughness } }],
    buffers: [{ byteLength: bin.byteLength }],
    bufferViews: [{ buffer: 0, byteOffset: 0, byteLength: p.byteLength }, { buffer: 0, byteOffset: p.byteLength, byteLength: p.byteLength },
                  { buffer: 0, byteOffset: 2 * p.byteLength, byteLength: ix.byteLength }],
    accessors: [{ bufferView: 0, componentType: 5126, count: n, type: 'VEC3', min: [-1, -1, -1], max: [1, 1, 1] },
                { bufferView: 1, componentType: 5126, count: n, type: 'VEC3' },
                { bufferView: 2, componentType: 5125, count: ix.length, type: 'SCALAR' }],
  });
  let jb = new TextEncoder().encode(json);
  const jlen = (jb.length + 3) & ~3, blen = (bin.length + 3) & ~3;
  const out = new Uint8Array(12 + 8 + jlen + 8 + blen);
  const dv = new DataView(out.buffer);
  dv.setUint32(0, 0x46546C67, true); dv.setUint32(4, 2, true); dv.setUint32(8, out.length, true);
  dv.setUint32(12, jlen, true); dv.setUint32(16, 0x4E4F534A, true);
  out.fill(0x20, 20, 20 + jlen); out.set(jb, 20);
  dv.setUint32(20 + jlen, blen, true); dv.setUint32(24 + jlen, 0x004E4942, true);
  out.set(bin, 28 + jlen);
  return out;
}
