// The three.js scene: renderer, camera, a sky dome that fades into the fog at the horizon,
// and sun plus sky light. Chunk meshes are added by ChunkMeshes.
import * as THREE from "three";

const SKY_TOP = new THREE.Color(0x4a7fc8);
const SKY_HORIZON = new THREE.Color(0xbcd4ea);

/**
 * @typedef {object} Stage
 * @property {THREE.WebGLRenderer} renderer
 * @property {THREE.Scene} scene
 * @property {THREE.PerspectiveCamera} camera
 * @property {() => void} resize  call when the window's size changed
 * @property {(far: number) => void} setFar  sets the far plane and the fog to a view's reach
 */

/**
 * Makes the renderer on a canvas and the scene around it.
 * @param {HTMLCanvasElement} canvas
 * @returns {Stage}
 */
export function createStage(canvas) {
  const renderer = new THREE.WebGLRenderer({ canvas, antialias: false, powerPreference: "high-performance" });
  renderer.setPixelRatio(Math.min(window.devicePixelRatio || 1, 1.5));
  renderer.setClearColor(SKY_HORIZON);
  const scene = new THREE.Scene();
  scene.fog = new THREE.Fog(SKY_HORIZON, 200, 1000);
  const camera = new THREE.PerspectiveCamera(65, 1, 0.5, 1000);
  camera.rotation.order = "YXZ";  // yaw, then pitch: fly controls
  scene.add(camera);

  const sky = skyDome();
  camera.add(sky);  // follows the camera: always around it, never reached
  scene.add(new THREE.HemisphereLight(0xd8e6ff, 0x4a3c30, 0.8));
  const sun = new THREE.DirectionalLight(0xfff0d8, 2.6);
  sun.position.set(0.75, 0.55, 0.35);  // a direction (it points at the origin): low, for relief
  scene.add(sun);

  const resize = () => {
    const w = canvas.clientWidth || window.innerWidth;
    const h = canvas.clientHeight || window.innerHeight;
    renderer.setSize(w, h, false);
    camera.aspect = w / h;
    camera.updateProjectionMatrix();
  };
  const setFar = (far) => {
    camera.far = far * 1.2;
    camera.updateProjectionMatrix();
    scene.fog.near = far * 0.35;
    scene.fog.far = far;
    sky.scale.setScalar(far * 1.1);
  };
  resize();
  return { renderer, scene, camera, resize, setFar };
}

/** A unit sphere seen from inside: horizon colour below, sky colour overhead. */
function skyDome() {
  const material = new THREE.ShaderMaterial({
    side: THREE.BackSide,
    depthWrite: false,
    fog: false,
    uniforms: { top: { value: SKY_TOP }, horizon: { value: SKY_HORIZON } },
    vertexShader: `varying vec3 vDir;
      void main() {
        vDir = (modelMatrix * vec4(position, 0.0)).xyz;
        gl_Position = projectionMatrix * viewMatrix * modelMatrix * vec4(position, 1.0);
        gl_Position.z = gl_Position.w;  // on the far plane: behind everything
      }`,
    fragmentShader: `uniform vec3 top; uniform vec3 horizon; varying vec3 vDir;
      void main() {
        float t = clamp(normalize(vDir).y * 2.5, 0.0, 1.0);
        gl_FragColor = vec4(mix(horizon, top, sqrt(t)), 1.0);
        #include <colorspace_fragment>
      }`,
  });
  const dome = new THREE.Mesh(new THREE.SphereGeometry(1, 24, 12), material);
  dome.renderOrder = -1;
  dome.frustumCulled = false;
  return dome;
}
