#!/usr/bin/env node
// Runs a TF.js graph model (model.json + weight shards) on inputs given as .npy files, with the
// pure-JS CPU backend of @tensorflow/tfjs, and writes every output as .npy. It is the independent
// reference that tests/test_tfjs_converter.py compares the converted ONNX files against.
//
//   node run.js MODEL_JSON OUT_DIR INPUT.npy [INPUT.npy ...]
//
// Each INPUT.npy (float32 or int32, little-endian, C order) is one run of the model's single
// input; the outputs go to OUT_DIR/<input stem>.<output name>.npy, the output name being the
// graph node name without ":0" (e.g. "Identity"). Modules are found through NODE_PATH (the test
// installs package.json's dependencies into .cache/tfjs_runner).
'use strict';

const fs = require('fs');
const path = require('path');
const tf = require('@tensorflow/tfjs');

const DTYPES = { '<f4': 'float32', '<i4': 'int32' };

function readNpy(file) {
  const buf = fs.readFileSync(file);
  if (buf.toString('latin1', 0, 6) !== '\x93NUMPY') throw new Error(`${file}: not a .npy file`);
  const major = buf[6];
  const headerLen = major === 1 ? buf.readUInt16LE(8) : buf.readUInt32LE(8);
  const start = major === 1 ? 10 : 12;
  const header = buf.toString('latin1', start, start + headerLen);
  const descr = /'descr':\s*'([^']+)'/.exec(header)[1];
  if (/'fortran_order':\s*True/.test(header)) throw new Error(`${file}: Fortran order is not supported`);
  const shape = /'shape':\s*\(([^)]*)\)/.exec(header)[1].split(',').map((s) => s.trim()).filter((s) => s).map(Number);
  const dtype = DTYPES[descr];
  if (!dtype) throw new Error(`${file}: dtype ${descr} is not supported (float32 or int32)`);
  const data = buf.subarray(start + headerLen);
  const ab = data.buffer.slice(data.byteOffset, data.byteOffset + data.byteLength);
  const values = dtype === 'float32' ? new Float32Array(ab) : new Int32Array(ab);
  return tf.tensor(values, shape, dtype);
}

function writeNpy(file, tensor) {
  const descr = { float32: '<f4', int32: '<i4', bool: '|u1' }[tensor.dtype];
  if (!descr) throw new Error(`output dtype ${tensor.dtype} is not supported`);
  const values = tensor.dtype === 'bool' ? Uint8Array.from(tensor.dataSync()) : tensor.dataSync();
  const shape = tensor.shape.length === 1 ? `(${tensor.shape[0]},)` : `(${tensor.shape.join(', ')})`;
  let header = `{'descr': '${descr}', 'fortran_order': False, 'shape': ${shape}, }`;
  header += ' '.repeat(64 - ((10 + header.length + 1) % 64)) + '\n';
  const pre = Buffer.alloc(10);
  pre.write('\x93NUMPY', 0, 'latin1');
  pre[6] = 1;
  pre[7] = 0;
  pre.writeUInt16LE(header.length, 8);
  fs.writeFileSync(file, Buffer.concat([pre, Buffer.from(header, 'latin1'), Buffer.from(values.buffer, values.byteOffset, values.byteLength)]));
}

// An IOHandler that reads model.json and its shards from disk (pure tfjs has no file:// loader).
function fileHandler(modelJson) {
  return {
    load: async () => {
      const json = JSON.parse(fs.readFileSync(modelJson, 'utf8'));
      const dir = path.dirname(modelJson);
      const specs = [];
      const shards = [];
      for (const group of json.weightsManifest) {
        specs.push(...group.weights);
        for (const p of group.paths) shards.push(fs.readFileSync(path.join(dir, p)));
      }
      const all = Buffer.concat(shards);
      return {
        modelTopology: json.modelTopology,
        format: json.format,
        generatedBy: json.generatedBy,
        convertedBy: json.convertedBy,
        signature: json.signature,
        userDefinedMetadata: json.userDefinedMetadata,
        weightSpecs: specs,
        weightData: all.buffer.slice(all.byteOffset, all.byteOffset + all.byteLength),
      };
    },
  };
}

async function main() {
  const [modelJson, outDir, ...inputs] = process.argv.slice(2);
  if (!modelJson || !outDir || inputs.length === 0) {
    process.stderr.write('usage: node run.js MODEL_JSON OUT_DIR INPUT.npy [INPUT.npy ...]\n');
    process.exit(2);
  }
  await tf.setBackend('cpu');
  await tf.ready();
  const model = await tf.loadGraphModel(fileHandler(modelJson));
  const outputNames = model.outputs.map((o) => o.name);
  fs.mkdirSync(outDir, { recursive: true });
  for (const file of inputs) {
    const x = readNpy(file);
    const t0 = Date.now();
    let ys;
    try {
      ys = model.execute(x, outputNames); // these graphs have no control flow
    } catch (err) {
      ys = await model.executeAsync(x, outputNames);
    }
    const ms = Date.now() - t0;
    if (!Array.isArray(ys)) ys = [ys];
    const stem = path.basename(file, '.npy');
    outputNames.forEach((name, i) => {
      writeNpy(path.join(outDir, `${stem}.${name.replace(/:0$/, '')}.npy`), ys[i]);
    });
    process.stdout.write(`${stem}: ${outputNames.length} outputs in ${ms} ms\n`);
    tf.dispose([x, ...ys]);
  }
  process.stdout.write(`tfjs ${tf.version.tfjs} backend ${tf.getBackend()}\n`);
}

main().catch((err) => {
  process.stderr.write(`${err.stack || err}\n`);
  process.exit(1);
});
