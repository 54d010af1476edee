// The tool bar (tool, radius, strength, material) and the pick: a ray from the camera
// through a pixel against the chunk meshes gives the world point an edit is centred on.
import * as THREE from "three";
import { TOOLS } from "./edits.js";
import { MATERIALS } from "./palette.js";

const raycaster = new THREE.Raycaster();
const ndc = new THREE.Vector2();

/**
 * The nearest terrain point under a pixel, in world voxels, or null when the ray meets none.
 * @param {THREE.Camera} camera
 * @param {HTMLElement} element the canvas
 * @param {number} x client pixels
 * @param {number} y client pixels
 * @param {THREE.Object3D} chunks the group of chunk meshes
 * @returns {number[]|null}
 */
export function pick(camera, element, x, y, chunks) {
  const r = element.getBoundingClientRect();
  ndc.set(((x - r.left) / r.width) * 2 - 1, -((y - r.top) / r.height) * 2 + 1);
  camera.updateMatrixWorld();  // the camera may have turned since the last frame drew
  raycaster.setFromCamera(ndc, camera);
  const hit = raycaster.intersectObject(chunks, true).find((h) => h.object.visible);
  return hit ? [hit.point.x, hit.point.y, hit.point.z] : null;
}

/** The tool bar's state and its controls in the page (#tools). */
export class ToolBar {
  /** @param {HTMLElement} root */
  constructor(root) {
    this.tool = "explode";
    this.settings = { radius: 6, strength: 2, material: 3, carve: false };
    const buttons = root.querySelector("#tool-buttons");
    for (const t of TOOLS) {
      const b = document.createElement("button");
      b.textContent = t.label;
      b.dataset.tool = t.id;
      b.addEventListener("click", () => this.select(t.id));
      buttons.append(b);
    }
    this.buttons = buttons;
    const material = /** @type {HTMLSelectElement} */ (root.querySelector("#material"));
    for (const m of MATERIALS) material.append(new Option(`${m.id} ${m.name}`, String(m.id)));
    material.value = String(this.settings.material);
    material.addEventListener("change", () => { this.settings.material = Number(material.value); });
    this.radius = this.#slider(root, "#radius", "radius");
    this.strength = this.#slider(root, "#strength", "strength");
    const carve = /** @type {HTMLInputElement} */ (root.querySelector("#carve"));
    carve.addEventListener("change", () => { this.settings.carve = carve.checked; });
    this.select(this.tool);
  }

  /** @param {string} id a TOOLS id */
  select(id) {
    this.tool = id;
    for (const b of this.buttons.children) b.classList.toggle("on", b.dataset.tool === id);
  }

  /**
   * Sets a setting and the control that shows it.
   * @param {"radius"|"strength"|"material"|"carve"} key
   * @param {number|boolean} value
   */
  set(key, value) {
    const input = /** @type {HTMLInputElement} */ (document.getElementById(key));
    if (key === "carve") input.checked = !!value;
    else input.value = String(value);
    input.dispatchEvent(new Event(key === "radius" || key === "strength" ? "input" : "change"));
  }

  /** Sets the sliders' ranges to the server's edit limits (Welcome). */
  setLimits(welcome) {
    if (welcome.maxEditRadius) this.radius.max = String(welcome.maxEditRadius);
    if (welcome.maxEditStrength) this.strength.max = String(welcome.maxEditStrength);
    for (const [input, key] of [[this.radius, "radius"], [this.strength, "strength"]]) {
      this.settings[key] = Math.min(this.settings[key], Number(input.max));
      input.value = String(this.settings[key]);
      input.dispatchEvent(new Event("input"));
    }
  }

  #slider(root, selector, key) {
    const input = /** @type {HTMLInputElement} */ (root.querySelector(selector));
    const label = root.querySelector(`${selector}-value`);
    input.value = String(this.settings[key]);
    const show = () => {
      this.settings[key] = Number(input.value);
      label.textContent = input.value;
    };
    input.addEventListener("input", show);
    show();
    return input;
  }
}
