// Chromium's fetch refuses file:// URLs, which the test pages' loaders use (three's KTX2Loader, the
// glTF viewer's WebAssembly): this classic script, loaded before a page's modules, reads them with
// XMLHttpRequest instead (allowed by --allow-file-access-from-files). window.readBytes(url) gives a
// file's bytes as a Uint8Array.
window.readBytes = (url) => new Promise((resolve, reject) => {
  const x = new XMLHttpRequest();
  x.open('GET', url);
  x.responseType = 'arraybuffer';
  x.onload = () => resolve(new Uint8Array(x.response));
  x.onerror = () => reject(new Error('cannot read ' + url));
  x.send();
});
(() => {
  const browserFetch = window.fetch;
  window.fetch = (input, init) => {
    const url = String(input instanceof Request ? input.url : input);
    if (!url.startsWith('file:')) return browserFetch(input, init);
    const type = url.endsWith('.wasm') ? 'application/wasm' : 'application/octet-stream';
    return window.readBytes(url).then((b) => new Response(b, { headers: { 'Content-Type': type } }));
  };
})();
