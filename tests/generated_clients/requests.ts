// Requests built with the types openapi-typescript generated from openapi/openapi.json
// (no-site.ts) and openapi/openapi-site.json (site.ts), type-checked by `tsc --noEmit`
// (tests/generated_clients.rs). The lines marked @ts-expect-error must fail to type-check:
// the documents say what a server without a site refuses.
import type { components as NoSite, operations as NoSiteOps } from "./no-site";
import type { components as Site, operations as SiteOps } from "./site";

const camera: NoSite["schemas"]["CameraPixels"] = { fx_px: 1000, fy_px: 1000, cx_px: 639.5, cy_px: 359.5 };
const corners_px: number[][] = [[589.2, 309.8], [689.9, 311.4], [688.1, 411.6], [588.0, 409.5]];

// Without a site: the camera's intrinsics and the marker size.
export const corners: NoSite["schemas"]["CornersRequest"] = {
  corners_px,
  camera,
  marker: { size_mm: 50 },
  solver: { method: "reprojection" },
};
export const planeCorners: NoSite["schemas"]["CornersRequest"] = {
  corners_mm: [[-1.2, -1.0], [1.2, -1.0], [1.2, 1.0], [-1.2, 1.0]],
  camera: { focal_length_mm: 4 },
  marker: { size_mm: 50 },
};
export const image: NoSiteOps["pose_from_image"]["requestBody"]["content"]["multipart/form-data"] = {
  image: "the photo's bytes",
  request: { camera, marker: { size_mm: 50 }, points: "finders" },
};
export const rawImageQuery: NoSiteOps["pose_from_image"]["parameters"]["query"] = {
  fx_px: 1000, fy_px: 1000, cx_px: 639.5, cy_px: 359.5, marker_size_mm: 50, effort: "fast",
};
// @ts-expect-error: without a site the marker size is required.
export const unsized: NoSite["schemas"]["CornersRequest"] = { corners_px, camera };
// @ts-expect-error: without a site there is no camera by id.
export const byId: NoSite["schemas"]["CornersRequest"] = { corners_px, camera: { id: "front" }, marker: { size_mm: 50 } };

// With a site: a camera by id, each code sized by its payload.
export const siteCorners: Site["schemas"]["CornersRequest"] = { corners_px, camera: { id: "front" }, payload: "LOC-0001" };
export const siteImage: SiteOps["pose_from_image"]["requestBody"]["content"]["multipart/form-data"] = {
  image: "the photo's bytes",
  request: { camera: { id: "front" } },
};
export const siteRawImageQuery: SiteOps["pose_from_image"]["parameters"]["query"] = { camera_id: "front" };
