// Reads a KTX2 file with ktx-parse (an independent reader) and prints, as JSON, its header,
// its data format descriptor, each level's size and byte length, and per level the
// solid-angle-weighted radiance integral and first moment of each channel, with each texel's
// direction taken from the KTX 2.0 specification's cube map addressing (faces +X, −X, +Y, −Y,
// +Z, −Z; the GL/Vulkan major-axis table; row 0 at t = 0):
//   +X: sc = −z, tc = −y   −X: sc = z, tc = −y   +Y: sc = x, tc = z
//   −Y: sc = x, tc = −z    +Z: sc = x, tc = −y   −Z: sc = −x, tc = −y
// With --texels L S it prints instead of the sums every S-th texel (rows and columns ≡ S/2 mod S) of level L
// as [x, y, z, r, g, b], the direction again from the specification's addressing. With --values it
// prints instead of the sums level 0's every channel value in the file's order (layers, faces, slices,
// rows, columns, channels), of any texture, cube or not.
// Usage: node ktx2_read.mjs FILE.ktx2 [--texels LEVEL STRIDE | --values]
import { readFileSync } from 'node:fs';
import { read } from 'ktx-parse';

const file = process.argv[2];
const texelsAt = process.argv[3] === '--texels' ? [Number(process.argv[4]), Number(process.argv[5])] : null;
const valuesOnly = process.argv[3] === '--values';
const c = read(new Uint8Array(readFileSync(file)));

function halfToFloat(h) {
  const s = h & 0x8000 ? -1 : 1, e = (h >> 10) & 0x1f, f = h & 0x3ff;
  if (e === 0) return s * f * 2 ** -24;
  if (e === 31) return f ? NaN : s * Infinity;
  return s * (1 + f / 1024) * 2 ** (e - 15);
}

// Direction of (sc, tc) ∈ [−1, 1]² on each face, inverting the table above.
const faceDir = [
  (sc, tc) => [1, -tc, -sc],
  (sc, tc) => [-1, -tc, sc],
  (sc, tc) => [sc, 1, tc],
  (sc, tc) => [sc, -1, -tc],
  (sc, tc) => [sc, -tc, 1],
  (sc, tc) => [-sc, -tc, -1],
];

const dfd = c.dataFormatDescriptor[0];
const out = {
  vkFormat: c.vkFormat, typeSize: c.typeSize, pixelWidth: c.pixelWidth, pixelHeight: c.pixelHeight,
  pixelDepth: c.pixelDepth, layerCount: c.layerCount, faceCount: c.faceCount, levelCount: c.levelCount,
  supercompressionScheme: c.supercompressionScheme,
  dfd: {
    vendorId: dfd.vendorId, descriptorType: dfd.descriptorType, versionNumber: dfd.versionNumber,
    colorModel: dfd.colorModel, colorPrimaries: dfd.colorPrimaries, transferFunction: dfd.transferFunction,
    flags: dfd.flags, texelBlockDimension: dfd.texelBlockDimension, bytesPlane: dfd.bytesPlane,
    samples: dfd.samples.map((s) => ({ bitOffset: s.bitOffset, bitLength: s.bitLength, channelType: s.channelType })),
  },
  keyValue: Object.fromEntries(Object.entries(c.keyValue).map(([k, v]) =>
    [k, typeof v === 'string' ? v : new TextDecoder().decode(v).replace(/\0$/, '')])),
  levels: [],
};
const bpc = c.typeSize;  // bytes per channel: 2 (half) or 4 (float)
for (let l = 0; l < c.levels.length; ++l) {
  const n = Math.max(1, c.pixelWidth >> l), data = c.levels[l].levelData;
  if (texelsAt || valuesOnly) {  // the texels alone: skip the per-level sums
    out.levels.push({ size: n, byteLength: data.byteLength, uncompressedByteLength: c.levels[l].uncompressedByteLength });
    continue;
  }
  const view = new DataView(data.buffer, data.byteOffset, data.byteLength);
  const faceBytes = data.byteLength / 6;
  const moments = [[0, 0, 0, 0], [0, 0, 0, 0], [0, 0, 0, 0]];
  let min = Infinity, max = -Infinity, finite = true;
  for (let f = 0; f < 6; ++f)
    for (let row = 0; row < n; ++row)
      for (let col = 0; col < n; ++col) {
        const sc = (2 * (col + 0.5)) / n - 1, tc = (2 * (row + 0.5)) / n - 1;
        const d = faceDir[f](sc, tc), len = Math.hypot(d[0], d[1], d[2]);
        const omega = 4 / (n * n) / len ** 3;  // texel-centre solid angle
        const at = f * faceBytes + (row * n + col) * 4 * bpc;
        for (let k = 0; k < 3; ++k) {
          const v = bpc === 2 ? halfToFloat(view.getUint16(at + 2 * k, true)) : view.getFloat32(at + 4 * k, true);
          if (!Number.isFinite(v)) finite = false;
          min = Math.min(min, v), max = Math.max(max, v);
          for (let j = 0; j < 3; ++j) moments[k][j] += (v * omega * d[j]) / len;
          moments[k][3] += v * omega;
        }
      }
  out.levels.push({ size: n, byteLength: data.byteLength, uncompressedByteLength: c.levels[l].uncompressedByteLength,
                    min, max, finite, moments });
}
if (texelsAt) {
  const [l, stride] = texelsAt, n = Math.max(1, c.pixelWidth >> l), data = c.levels[l].levelData;
  const view = new DataView(data.buffer, data.byteOffset, data.byteLength), faceBytes = data.byteLength / 6;
  out.texels = [];
  for (let f = 0; f < 6; ++f)
    for (let row = stride >> 1; row < n; row += stride)
      for (let col = stride >> 1; col < n; col += stride) {
        const d = faceDir[f]((2 * (col + 0.5)) / n - 1, (2 * (row + 0.5)) / n - 1), len = Math.hypot(d[0], d[1], d[2]);
        const at = f * faceBytes + (row * n + col) * 4 * bpc, v = [];
        for (let k = 0; k < 3; ++k)
          v.push(bpc === 2 ? halfToFloat(view.getUint16(at + 2 * k, true)) : view.getFloat32(at + 4 * k, true));
        out.texels.push([d[0] / len, d[1] / len, d[2] / len, ...v]);
      }
}
if (valuesOnly) {
  const data = c.levels[0].levelData, view = new DataView(data.buffer, data.byteOffset, data.byteLength);
  out.values = [];
  for (let at = 0; at < data.byteLength; at += bpc)
    out.values.push(bpc === 2 ? halfToFloat(view.getUint16(at, true)) : view.getFloat32(at, true));
}
process.stdout.write(JSON.stringify(out) + '\n');
