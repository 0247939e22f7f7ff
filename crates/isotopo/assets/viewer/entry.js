// What the HTML report's 3D view takes from three.js: bundled by build.sh into one script that
// defines the global THREE (the report embeds it; nothing is fetched).
export {
  AmbientLight, BufferAttribute, BufferGeometry, CylinderGeometry, Float32BufferAttribute,
  MeshBasicMaterial, Quaternion, Color, DirectionalLight, DoubleSide, Group,
  Line, LineBasicMaterial, LineLoop, LineSegments, Matrix4, Mesh, MeshLambertMaterial, Plane,
  PerspectiveCamera, Points, PointsMaterial, Scene, Sphere, Vector3, WebGLRenderer, Box3,
} from 'three';
export { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js';
