// Where the camera looks from: the first view, a fit of whatever is drawn, views along the axes.
import * as THREE from 'three';

/** The half-angle (rad) that bounds the view in both directions. */
function halfAngle(camera) {
  const v = THREE.MathUtils.degToRad(camera.fov) / 2;
  return Math.min(v, Math.atan(Math.tan(v) * camera.aspect));
}

/** Puts the whole of `sphere` in view, looking along `direction` (from the camera, unit). */
export function fit(camera, controls, sphere, direction) {
  const r = Math.max(sphere.radius, 1e-9);
  const dist = (1.1 * r) / Math.sin(halfAngle(camera));
  controls.target.copy(sphere.center);
  camera.position.copy(sphere.center).addScaledVector(direction, -dist);
  camera.near = dist / 1000; camera.far = dist * 100;
  // Looking straight along z, "up" must not be z.
  camera.up.set(0, 0, 1);
  if (Math.abs(direction.z) > 0.999) camera.up.set(0, 1, 0);
  camera.updateProjectionMatrix();
  controls.update();
}

/** The first view: from the front, right and above, like an engineering isometric. */
export const HOME = new THREE.Vector3(-0.25, 1.45, -0.7).normalize();

/** Looking from the +axis side (sign 1) or the −axis side (−1) toward the part. */
export function along(axis, sign) {
  const d = new THREE.Vector3();
  d.setComponent('xyz'.indexOf(axis), -sign);
  return d;
}
