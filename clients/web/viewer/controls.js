// Fly controls: WASD to move, Space/E up, Q/C down, Shift faster; drag with the mouse to
// look. A press released without dragging is a click, handed to onClick (the tools).
import * as THREE from "three";

const DRAG_PX = 5;  // a press that moves less than this is a click, not a look

export class FlyControls {
  /**
   * @param {THREE.Camera} camera with rotation.order "YXZ"
   * @param {HTMLElement} element that takes the mouse
   * @param {{speed?: number, onClick?: (x: number, y: number) => void}} [options]
   *   speed in voxels per second; onClick gets client pixel coordinates
   */
  constructor(camera, element, options = {}) {
    this.camera = camera;
    this.element = element;
    this.speed = options.speed ?? 40;
    this.onClick = options.onClick ?? (() => {});
    this.keys = new Set();
    this.drag = null;
    this.yaw = camera.rotation.y;
    this.pitch = camera.rotation.x;
    this.forward = new THREE.Vector3();
    this.right = new THREE.Vector3();

    element.addEventListener("contextmenu", (e) => e.preventDefault());
    element.addEventListener("pointerdown", (e) => {
      this.drag = { x: e.clientX, y: e.clientY, startX: e.clientX, startY: e.clientY, moved: false, button: e.button };
      element.setPointerCapture?.(e.pointerId);
    });
    element.addEventListener("pointermove", (e) => {
      const d = this.drag;
      if (!d) return;
      if (Math.hypot(e.clientX - d.startX, e.clientY - d.startY) >= DRAG_PX) d.moved = true;
      if (!d.moved) return;
      this.look((e.clientX - d.x) * 0.004, (e.clientY - d.y) * 0.004);
      d.x = e.clientX;
      d.y = e.clientY;
    });
    element.addEventListener("pointerup", (e) => {
      const d = this.drag;
      this.drag = null;
      if (d && !d.moved && d.button === 0) this.onClick(e.clientX, e.clientY);
    });
    const typing = (e) => e.target instanceof HTMLInputElement || e.target instanceof HTMLSelectElement;
    window.addEventListener("keydown", (e) => { if (!typing(e)) this.keys.add(e.code); });
    window.addEventListener("keyup", (e) => this.keys.delete(e.code));
    window.addEventListener("blur", () => this.keys.clear());
  }

  /** Turns the camera by a yaw and a pitch (radians); the pitch stays within ±89°. */
  look(dYaw, dPitch) {
    this.yaw -= dYaw;
    this.pitch = Math.max(-1.55, Math.min(1.55, this.pitch - dPitch));
    this.camera.rotation.set(this.pitch, this.yaw, 0);
  }

  /** Sets where the camera looks: yaw and pitch in radians. */
  setAngles(yaw, pitch) {
    this.yaw = yaw;
    this.pitch = 0;
    this.look(0, -pitch);
  }

  /** Moves the camera for the keys held. @param {number} dt seconds */
  update(dt) {
    const k = this.keys;
    const ax = (k.has("KeyD") ? 1 : 0) - (k.has("KeyA") ? 1 : 0);
    const az = (k.has("KeyW") ? 1 : 0) - (k.has("KeyS") ? 1 : 0);
    const ay = (k.has("Space") || k.has("KeyE") ? 1 : 0) - (k.has("KeyQ") || k.has("KeyC") ? 1 : 0);
    if (!ax && !ay && !az) return;
    const fast = k.has("ShiftLeft") || k.has("ShiftRight") ? 6 : 1;
    const step = this.speed * fast * Math.min(dt, 0.1);
    this.camera.getWorldDirection(this.forward);
    this.right.crossVectors(this.forward, this.camera.up).normalize();
    this.camera.position.addScaledVector(this.forward, az * step);
    this.camera.position.addScaledVector(this.right, ax * step);
    this.camera.position.y += ay * step;
  }
}
