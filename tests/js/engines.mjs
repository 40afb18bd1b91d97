// Loads a `prtbake ibl` package with the engines' own code and prints, as JSON, what each engine
// makes of it, for test_engines.cpp to compare with prtbake's own values.
//   three.js: ObjectLoader.parse(threejs/light_probe.json), then the LightProbe's
//             sh.getAt(d) (radiance) and sh.getIrradianceAt(d) (irradiance) at each direction;
//   Filament: Ktx1Bundle(filament/ibl.ktx) as createIblFromKtx1 reads it (format, levels, cube,
//             the "sh" key parsed the same way), IndirectLight.getColorEstimate(sh, −d) (Filament's
//             evaluation of its SH: π·max(0, the shader's polynomial) = irradiance at normal d),
//             the same for the numbers of sh.txt, and every STRIDE-th texel of each level's
//             getCubeBlob, unpacked from GL_UNSIGNED_INT_10F_11F_11F_REV.
//   Babylon.js: babylon/environment.env through GetEnvInfo and
//             CreateRadianceImageDataArrayBufferViews (the manifest and the image views its
//             loader makes), UploadEnvSpherical (the polynomial it reads), then the PBR shader's
//             computeEnvironmentIrradiance, taken from Babylon's shader source and evaluated per
//             channel, on the harmonics the shader gets (preScaledHarmonics). The same for the
//             light of babylon/environment.glb, its coefficients taken through the calls of
//             Babylon's EXT_lights_image_based loader (which needs a WebGL engine to run whole).
//             Babylon's value × π is the irradiance at world normal d: Babylon's scene is
//             left-handed and its glTF loader puts glTF's (x, y, z) at (−x, y, z).
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

// --- Babylon.js ---
async function babylon() {
  if (!existsSync(`${dir}/babylon/environment.env`)) return;
  const env = await import('@babylonjs/core/Misc/environmentTextureTools.js');
  const { SphericalHarmonics, SphericalPolynomial } = await import('@babylonjs/core/Maths/sphericalPolynomial.js');
  const { harmonicsFunctions } = await import('@babylonjs/core/Shaders/ShadersInclude/harmonicsFunctions.js');
  // The SPHERICAL_HARMONICS branch of the shader's computeEnvironmentIrradiance, per channel.
  const m = /#ifdef SPHERICAL_HARMONICS\s*vec3 computeEnvironmentIrradiance\(vec3 normal\) \{return ([^;]*);\}/.exec(harmonicsFunctions.shader);
  if (!m) throw new Error('computeEnvironmentIrradiance not found in Babylon\'s shader source');
  const shader = new Function('H', 'normal', `return ${m[1].replace(/vSpherical(\w+)/g, 'H.$1')};`);
  const evaluate = (harmonics) => dirs.map(([x, y, z]) => {
    const normal = { x: -x, y, z };
    return ['x', 'y', 'z'].map((c) => Math.PI * shader({
      L00: harmonics.l00[c], L1_1: harmonics.l1_1[c], L10: harmonics.l10[c], L11: harmonics.l11[c],
      L2_2: harmonics.l2_2[c], L2_1: harmonics.l2_1[c], L20: harmonics.l20[c], L21: harmonics.l21[c], L22: harmonics.l22[c],
    }, normal));
  });
  const bytes = new Uint8Array(readFileSync(`${dir}/babylon/environment.env`));
  const info = env.GetEnvInfo(bytes);
  const views = env.CreateRadianceImageDataArrayBufferViews(bytes, info);
  const pngMagic = (v) => v[0] === 0x89 && v[1] === 0x50 && v[2] === 0x4e && v[3] === 0x47;
  const texture = {};
  env.UploadEnvSpherical(texture, info);
  const gl = readFileSync(`${dir}/babylon/environment.glb`);
  const json = JSON.parse(gl.subarray(20, 20 + gl.readUInt32LE(12)).toString('utf8'));
  const light = json.extensions.EXT_lights_image_based.lights[json.scenes[0].extensions.EXT_lights_image_based.light];
  // As EXT_lights_image_based._loadLightAsync: FromArray, × intensity, ÷ π, FromHarmonics.
  const sh = SphericalHarmonics.FromArray(light.irradianceCoefficients);
  sh.scaleInPlace(light.intensity);
  sh.convertIrradianceToLambertianRadiance();
  const fromGlb = SphericalPolynomial.FromHarmonics(sh);
  out.babylon = {
    env: {
      version: info.version, width: info.width, imageType: info.imageType,
      lodGenerationScale: info.specular.lodGenerationScale, levels: views.length,
      faceSizes: views.map((level) => level.length),
      allPng: views.every((level) => level.every(pngMagic)),
      irradiance: evaluate(texture._sphericalPolynomial.preScaledHarmonics),
    },
    glb: {
      specularImageSize: light.specularImageSize, levels: light.specularImages.length,
      images: json.images.length, irradiance: evaluate(fromGlb.preScaledHarmonics),
    },
  };
}

await filament();
await babylon();
process.stdout.write(JSON.stringify(out) + '\n');
