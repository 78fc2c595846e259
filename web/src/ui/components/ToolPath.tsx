// The tool path in 3-D (perspective, orbit) and in the top, front, side and iso views
// (orthographic): rapids and feeds in their colours, what has run highlighted (a uniform:
// a million segments are drawn without touching their buffer again), the live tool as a
// cone with its trail. It draws only when something changed.
import { useEffect, useRef, useState } from 'preact/hooks';
import * as THREE from 'three';
import { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js';
import { type PathChain, simplifyForDrawing } from '../../api/preview';
import type { Status } from '../../api/types';
import { toolInChainFrame } from '../../state/store';

export type View = '3d' | 'top' | 'front' | 'side' | 'iso';
const VIEWS: [View, string][] = [
  ['3d', '3-D'],
  ['top', 'Top'],
  ['front', 'Front'],
  ['side', 'Side'],
  ['iso', 'Iso'],
];

export const COLORS = {
  feed: '#e8eef5',
  rapid: '#ffa726',
  feedDone: '#00e5ff',
  rapidDone: '#00838f',
  tool: '#ffeb3b',
  trail: '#ff4081',
  background: '#101419',
};

const vertexShader = `
attribute float kind;
attribute float index;
uniform float executed;
flat varying float vKind;
flat varying float vDone;
void main() {
  vKind = kind;
  vDone = index <= executed ? 1.0 : 0.0;
  gl_Position = projectionMatrix * modelViewMatrix * vec4(position, 1.0);
}`;

const fragmentShader = `
uniform vec3 feed;
uniform vec3 rapid;
uniform vec3 feedDone;
uniform vec3 rapidDone;
flat varying float vKind;
flat varying float vDone;
void main() {
  vec3 c = vKind < 1.5 ? (vDone > 0.5 ? rapidDone : rapid) : (vDone > 0.5 ? feedDone : feed);
  gl_FragColor = vec4(c, 1.0);
}`;

const TRAIL = 50_000;
/**
 * Above this many points the path is drawn simplified to a 5000th of its extent (well under
 * a pixel of the panel at full view): software GL, as in a VM, rasterises a million
 * segments in seconds.
 */
const DRAW_ALL_UP_TO = 200_000;

class Scene {
  renderer: THREE.WebGLRenderer;
  scene = new THREE.Scene();
  perspective = new THREE.PerspectiveCamera(40, 1, 0.1, 100_000);
  ortho = new THREE.OrthographicCamera(-1, 1, 1, -1, -100_000, 100_000);
  camera: THREE.Camera = this.perspective;
  controls: OrbitControls;
  path: THREE.Line | null = null;
  material = new THREE.ShaderMaterial({
    vertexShader,
    fragmentShader,
    uniforms: {
      executed: { value: -1 },
      feed: { value: new THREE.Color(COLORS.feed) },
      rapid: { value: new THREE.Color(COLORS.rapid) },
      feedDone: { value: new THREE.Color(COLORS.feedDone) },
      rapidDone: { value: new THREE.Color(COLORS.rapidDone) },
    },
  });
  tool: THREE.Mesh;
  trail: THREE.Line;
  trailCount = 0;
  grid: THREE.Group = new THREE.Group();
  view: View = '3d';
  box = new THREE.Box3(new THREE.Vector3(-10, -10, -10), new THREE.Vector3(10, 10, 10));
  pending = false;
  width = 1;
  height = 1;
  /** Milliseconds each frame took to draw (for the measurements in docs/hmi.md). */
  frameMs: number[] = [];
  /** Points of the path drawn. */
  drawn = 0;

  constructor(canvas: HTMLCanvasElement) {
    this.renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
    this.renderer.setPixelRatio(Math.min(window.devicePixelRatio, 2));
    this.renderer.setClearColor(COLORS.background);
    for (const c of [this.perspective, this.ortho]) c.up.set(0, 0, 1);
    this.controls = new OrbitControls(this.perspective, canvas);
    this.controls.addEventListener('change', () => this.draw());
    const cone = new THREE.ConeGeometry(1, 3, 16);
    cone.rotateX(-Math.PI / 2);
    cone.translate(0, 0, 1.5);
    this.tool = new THREE.Mesh(cone, new THREE.MeshBasicMaterial({ color: COLORS.tool }));
    this.tool.visible = false;
    const trailGeometry = new THREE.BufferGeometry();
    trailGeometry.setAttribute('position', new THREE.BufferAttribute(new Float32Array(TRAIL * 3), 3));
    trailGeometry.setDrawRange(0, 0);
    this.trail = new THREE.Line(trailGeometry, new THREE.LineBasicMaterial({ color: COLORS.trail }));
    this.trail.frustumCulled = false;
    this.scene.add(this.tool, this.trail, this.grid);
  }

  setChain(chain: PathChain | null) {
    if (this.path) {
      this.scene.remove(this.path);
      this.path.geometry.dispose();
      this.path = null;
    }
    this.drawn = 0;
    if (chain && chain.count > 0) {
      const g = new THREE.BufferGeometry();
      const extent = Math.hypot(...chain.max.map((v, i) => v - chain.min[i]));
      const d =
        chain.count > DRAW_ALL_UP_TO
          ? simplifyForDrawing(chain, extent / 5000)
          : { positions: chain.positions, kinds: chain.kinds, index: Float32Array.from({ length: chain.count }, (_, i) => i), count: chain.count };
      this.drawn = d.count;
      g.setAttribute('position', new THREE.BufferAttribute(d.positions, 3));
      g.setAttribute('kind', new THREE.BufferAttribute(d.kinds, 1));
      g.setAttribute('index', new THREE.BufferAttribute(d.index, 1));
      this.path = new THREE.Line(g, this.material);
      this.path.frustumCulled = false;
      this.scene.add(this.path);
      this.box.set(new THREE.Vector3(...chain.min), new THREE.Vector3(...chain.max));
    } else {
      this.box.set(new THREE.Vector3(-10, -10, -10), new THREE.Vector3(10, 10, 10));
    }
    this.trailCount = 0;
    this.trail.geometry.setDrawRange(0, 0);
    this.makeGrid();
    this.setView(this.view);
  }

  setExecuted(index: number) {
    this.material.uniforms.executed.value = index;
    this.draw();
  }

  setTool(p: [number, number, number] | null) {
    if (!p) {
      this.tool.visible = false;
      this.draw();
      return;
    }
    const moved = !this.tool.visible || this.tool.position.distanceToSquared(new THREE.Vector3(...p)) > 1e-6;
    this.tool.visible = true;
    this.tool.position.set(...p);
    if (moved) {
      const attr = this.trail.geometry.getAttribute('position') as THREE.BufferAttribute;
      if (this.trailCount >= TRAIL) {
        // Keep the newer half.
        const a = attr.array as Float32Array;
        a.copyWithin(0, (TRAIL / 2) * 3, TRAIL * 3);
        this.trailCount = TRAIL / 2;
      }
      attr.setXYZ(this.trailCount++, ...p);
      attr.needsUpdate = true;
      this.trail.geometry.setDrawRange(0, this.trailCount);
      this.draw();
    }
  }

  clearTrail() {
    this.trailCount = 0;
    this.trail.geometry.setDrawRange(0, 0);
    this.draw();
  }

  private size(): number {
    const s = new THREE.Vector3();
    this.box.getSize(s);
    return Math.max(s.x, s.y, s.z, 1);
  }

  private makeGrid() {
    this.grid.clear();
    const size = this.size();
    // Grid lines at a round step under the part, in the XY plane at the lowest Z.
    const step = 10 ** Math.floor(Math.log10(size / 2));
    const c = new THREE.Vector3();
    this.box.getCenter(c);
    const half = Math.ceil((size * 0.75) / step) * step;
    const grid = new THREE.GridHelper(2 * half, Math.round((2 * half) / step), 0x3a4654, 0x252d36);
    grid.rotateX(Math.PI / 2);
    grid.position.set(Math.round(c.x / step) * step, Math.round(c.y / step) * step, this.box.min.z);
    this.grid.add(grid);
    const axes = new THREE.AxesHelper(step);
    this.grid.add(axes);
    this.tool.scale.setScalar(size / 60);
  }

  setView(view: View) {
    this.view = view;
    const c = new THREE.Vector3();
    this.box.getCenter(c);
    const size = this.size();
    const dirs: Record<View, [number, number, number]> = {
      '3d': [0.9, -1.4, 1.0],
      top: [0, 0, 1],
      front: [0, -1, 0],
      side: [1, 0, 0],
      iso: [1, -1, 1],
    };
    const d = new THREE.Vector3(...dirs[view]).normalize();
    const cam = view === '3d' ? this.perspective : this.ortho;
    this.camera = cam;
    cam.up.set(0, view === 'top' ? 1 : 0, view === 'top' ? 0 : 1);
    cam.position.copy(c).addScaledVector(d, size * 2.2);
    cam.lookAt(c);
    this.ortho.zoom = 1;
    this.fitOrtho(size);
    this.controls.object = cam;
    this.controls.target.copy(c);
    this.controls.enableRotate = view === '3d' || view === 'iso';
    this.controls.update();
    this.draw();
  }

  private fitOrtho(size: number) {
    const aspect = this.width / this.height;
    const half = size * 0.65;
    this.ortho.left = -half * Math.max(aspect, 1);
    this.ortho.right = half * Math.max(aspect, 1);
    this.ortho.top = half / Math.min(aspect, 1);
    this.ortho.bottom = -half / Math.min(aspect, 1);
    this.ortho.updateProjectionMatrix();
  }

  resize(w: number, h: number) {
    this.width = Math.max(w, 1);
    this.height = Math.max(h, 1);
    this.renderer.setSize(this.width, this.height, false);
    this.perspective.aspect = this.width / this.height;
    this.perspective.updateProjectionMatrix();
    this.fitOrtho(this.size());
    this.draw();
  }

  draw() {
    if (this.pending) return;
    this.pending = true;
    requestAnimationFrame(() => {
      this.pending = false;
      const t0 = performance.now();
      this.renderer.render(this.scene, this.camera);
      if (this.frameMs.length < 100_000) this.frameMs.push(performance.now() - t0);
    });
  }

  dispose() {
    this.controls.dispose();
    this.path?.geometry.dispose();
    this.renderer.dispose();
  }
}

interface Props {
  chain: PathChain | null;
  /** Index of the last point run (-1: nothing). */
  executed?: number;
  /** Follow the live tool. */
  live?: boolean;
  subscribe?: (f: (s: Status) => void) => () => void;
  label: string;
  testid?: string;
}

export function ToolPath({ chain, executed = -1, live = false, subscribe, label, testid }: Props) {
  const canvas = useRef<HTMLCanvasElement>(null);
  const scene = useRef<Scene | null>(null);
  const [view, setView] = useState<View>('3d');
  const [error, setError] = useState<string | null>(null);

  useEffect(() => {
    try {
      const s = new Scene(canvas.current!);
      scene.current = s;
      (window as unknown as { __toolpath?: Scene }).__toolpath = s;
      const ro = new ResizeObserver(([e]) => s.resize(e.contentRect.width, e.contentRect.height));
      ro.observe(canvas.current!.parentElement!);
      return () => {
        ro.disconnect();
        s.dispose();
      };
    } catch (e) {
      setError(`The tool path needs WebGL, which this browser does not give: ${(e as Error).message}`);
      return undefined;
    }
  }, []);
  useEffect(() => scene.current?.setChain(chain), [chain]);
  useEffect(() => scene.current?.setExecuted(executed), [executed, chain]);
  useEffect(() => {
    if (!live || !subscribe) return undefined;
    return subscribe((st) => scene.current?.setTool(toolInChainFrame(st)));
  }, [live, subscribe]);

  const dims = chain
    ? `X ${chain.min[0].toFixed(1)} … ${chain.max[0].toFixed(1)}  Y ${chain.min[1].toFixed(1)} … ${chain.max[1].toFixed(1)}  Z ${chain.min[2].toFixed(1)} … ${chain.max[2].toFixed(1)} mm`
    : 'no program';
  return (
    <figure class="toolpath" data-testid={testid} data-points={chain?.count ?? 0} data-executed={executed}>
      <div class="toolpath-views" role="group" aria-label="View">
        {VIEWS.map(([v, name]) => (
          <button
            type="button"
            class={`btn small ${v === view ? 'primary' : ''}`}
            aria-pressed={v === view}
            onClick={() => {
              setView(v);
              scene.current?.setView(v);
            }}
          >
            {name}
          </button>
        ))}
        {live && (
          <button type="button" class="btn small" onClick={() => scene.current?.clearTrail()}>
            Clear trail
          </button>
        )}
      </div>
      <div class="toolpath-canvas">
        <canvas ref={canvas} role="img" aria-label={`${label}: ${dims}`} />
        {error && <p class="why">{error}</p>}
      </div>
      <figcaption>
        <span class="key feed">feed</span> <span class="key rapid">rapid</span> <span class="key done">run</span>
        {live && <span class="key tool">tool</span>} <span class="dims">{dims}</span>
      </figcaption>
    </figure>
  );
}
