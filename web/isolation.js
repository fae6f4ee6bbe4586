// Cross-origin isolation where the server sends no COOP/COEP headers (a plain static server,
// object storage): the viewer's threads need SharedArrayBuffer, which browsers give only to
// isolated pages. Loaded two ways: as a page script it registers itself as the page's service
// worker and reloads the page once; as that service worker it adds the two headers to every
// same-origin response. Service workers need a secure context (https, or localhost).
if (typeof window === 'undefined') {
  self.addEventListener('install', () => self.skipWaiting());
  self.addEventListener('activate', (event) => event.waitUntil(self.clients.claim()));
  self.addEventListener('fetch', (event) => {
    const request = event.request;
    if (request.cache === 'only-if-cached' && request.mode !== 'same-origin') return;
    if (new URL(request.url).origin !== self.location.origin) return;
    event.respondWith(
      fetch(request).then((response) => {
        if (response.status === 0) return response;
        const headers = new Headers(response.headers);
        headers.set('Cross-Origin-Opener-Policy', 'same-origin');
        headers.set('Cross-Origin-Embedder-Policy', 'require-corp');
        return new Response(response.body, {
          status: response.status,
          statusText: response.statusText,
          headers,
        });
      }),
    );
  });
} else if (!window.crossOriginIsolated && window.isSecureContext && navigator.serviceWorker) {
  // One reload: a page the worker does not make isolated (a browser that refuses) still starts,
  // and says why it cannot run threads.
  const key = 'stipple-isolation-reloaded';
  if (!sessionStorage.getItem(key)) {
    window.stippleIsolating = true;
    sessionStorage.setItem(key, '1');
    navigator.serviceWorker
      .register(document.currentScript.src)
      .then(() => navigator.serviceWorker.ready)
      .then(() => location.reload());
  }
} else if (window.crossOriginIsolated) {
  sessionStorage.removeItem('stipple-isolation-reloaded');
}
