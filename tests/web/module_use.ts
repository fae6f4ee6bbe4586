// A page's use of stipple.mjs, type-checked against stipple.d.ts by tests/web/module.test.mjs
// (tsc --strict: a misuse of the API fails the compile).
import { createViewer, decodeViewState, encodeViewState, type Camera, type LoadInfo, type Stats,
         type Viewer } from './stipple.mjs';

export async function embed(element: HTMLElement): Promise<Viewer> {
  const viewer: Viewer = await createViewer(element, { url: 'tiles/tileset.json', pointSize: 2, hash: true });
  viewer.on('load', (info: LoadInfo) => console.log(`${info.points} points, ${info.renderer}`));
  viewer.on('error', (e: Error) => console.error(e.message));
  const off = viewer.on('camera', (c: Camera) => console.log(c.position[2], c.fov));
  off();
  viewer.setOptions({ color: 'classification', budget: 1_000_000, edl: false, edlStrength: 120 });
  const camera = viewer.camera;
  if (camera) viewer.camera = { position: camera.position, target: [0, 0, camera.target[2]] };
  const stats: Stats | null = viewer.stats();
  const png: Blob = await viewer.screenshot();
  const pixels: ImageData = await viewer.pixels();
  console.log(stats?.frames, png.size, pixels.width, viewer.options?.shown);
  location.hash = encodeViewState({ ...viewer.viewState(), ...decodeViewState(location.hash) });
  await viewer.open('other.copc.laz');
  return viewer;
}

export async function done(viewer: Viewer): Promise<void> {
  await viewer.destroy();
}
