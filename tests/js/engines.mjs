// Loads a `prtbake ibl` package with the engines' own code and prints, as JSON, what each engine
// makes of it, for test_engines.cpp to compare with prtbake's own values.
//   three.js: ObjectLoader.parse(threejs/light_probe.json), then the LightProbe's
//             sh.getAt(d) (radiance) and sh.getIrradianceAt(d) (irradiance) at each direction;
//   Filament: Ktx1Bundle(filament/ibl.ktx) as createIblFromKtx1 reads it (format, levels, cube,
//             the "sh" key parsed the same way), IndirectLight.getColorEstimate(sh, −d) (Filament's
//             evaluation of its SH: π·max(0, the shader's polynomial) = irradiance at normal d),
//             the same for the numbers of sh.txt, and every STRIDE-th texel of each level's
//             getCubeBlob, unpacked from GL_UNSIGNED_INT_10F_11F_11F_REV.
// Usage: node engines.mjs PACKAGE_DIR DIRECTIONS.json STRIDE
//   DIRECTIONS.json: [[x, y, z], ...] unit vectors.
import { createRequire } from 'node:module';
import { existsSync, readFileSync } from 'node:fs';
import vm from 'node:vm';
import { ObjectLoader, Vector3 } from 'three';

const [dir, dirsFile, strideText] = process.argv.slice(2);
const dirs = JSON.parse(readFileSync(dirsFile, 'utf8'));
const stride = Number(strideText || 7);
const out = { package: dir };

// --- three.js ---
if (existsSync(`${dir}/threejs/light_probe.json`)) {
  const probe = new ObjectLoader().parse(JSON.parse(readFileSync(`${dir}/threejs/light_probe.json`, 'utf8')));
  const radiance = [], irradiance = [];
  const c = new Vector3();
  for (const [x, y, z] of dirs) {
    const n = new Vector3(x, y, z);
    const r = probe.sh.getAt(n, c.clone());
    radiance.push([r.x, r.y, r.z]);
    const e = probe.sh.getIrradianceAt(n, c.clone());
    irradiance.push([e.x, e.y, e.z]);
  }
  out.three = { type: probe.type, isLightProbe: probe.isLightProbe === true, intensity: probe.intensity, radiance, irradiance };
}

// --- Filament ---
// filament.js is an Emscripten script that expects CommonJS globals; Filament.init loads the wasm.
const require = createRequire(import.meta.url);
const filamentFile = require.resolve('filament');
globalThis.require = require;
globalThis.__dirname = filamentFile.replace(/\/[^/]*$/, '');
globalThis.__filename = filamentFile;
vm.runInThisContext(readFileSync(filamentFile, 'utf8'), { filename: filamentFile });

function unpackUf(bits, mantissaBits) {
  const e = bits >> mantissaBits, m = bits & ((1 << mantissaBits) - 1);
  if (e === 0) return (m / (1 << mantissaBits)) * 2 ** -14;
  if (e === 31) return m ? NaN : Infinity;
  return (1 + m / (1 << mantissaBits)) * 2 ** (e - 15);
}

function filament() {
  if (!existsSync(`${dir}/filament/ibl.ktx`)) return Promise.resolve();
  return new Promise((resolve) => globalThis.Filament.init([], () => { readFilament(); resolve(); }));
}

function readFilament() {
  const F = globalThis.Filament;
  const bytes = new Uint8Array(readFileSync(`${dir}/filament/ibl.ktx`));
  const ktx = new F.Ktx1Bundle(F.Buffer(bytes));
  // As Filament._createIblFromKtx1 parses it.
  const shKey = ktx.getMetadata('sh').split(/\s/, 9 * 3).map(parseFloat);
  // sh.txt as cmgen writes it: the numbers inside the parentheses.
  const shTxt = readFileSync(`${dir}/filament/sh.txt`, 'utf8').split('\n').filter((l) => l.includes('('))
    .flatMap((l) => l.slice(l.indexOf('(') + 1, l.indexOf(')')).split(',').map(parseFloat));
  const estimate = (sh) => dirs.map(([x, y, z]) => {
    const c = F.IndirectLight.getColorEstimate(sh, [-x, -y, -z]);
    // c = (rgb / I, I), I the largest channel; all channels clamped to 0 give I = 0 and 0/0.
    return c[3] > 0 ? [c[0] * c[3], c[1] * c[3], c[2] * c[3]] : [0, 0, 0];
  });
  const levels = [];
  for (let l = 0; l < ktx.getNumMipLevels(); ++l) {
    const blob = ktx.getCubeBlob(l);
    const words = new Uint32Array(blob.buffer, blob.byteOffset, blob.byteLength / 4);
    const size = Math.round(Math.sqrt(words.length / 6));
    const texels = [];
    for (let t = stride >> 1; t < words.length; t += stride) {
      const w = words[t];
      texels.push([t, unpackUf(w & 0x7ff, 6), unpackUf((w >>> 11) & 0x7ff, 6), unpackUf(w >>> 22, 5)]);
    }
    levels.push({ size, texels });
  }
  const info = ktx.info();
  const sky = new F.Ktx1Bundle(F.Buffer(new Uint8Array(readFileSync(`${dir}/filament/skybox.ktx`))));
  out.filament = {
    glInternalFormat: info.glInternalFormat, glFormat: info.glFormat, glType: info.glType,
    isCubemap: ktx.isCubemap(), levelCount: ktx.getNumMipLevels(), shKey, shTxt,
    irradianceKey: estimate(shKey), irradianceTxt: estimate(shTxt), levels,
    skybox: { isCubemap: sky.isCubemap(), levelCount: sky.getNumMipLevels(), glInternalFormat: sky.info().glInternalFormat, size: sky.info().pixelWidth },
  };
}

await filament();
process.stdout.write(JSON.stringify(out) + '\n');
