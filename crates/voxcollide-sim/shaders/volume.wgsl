// Simulation pass 0, for a body filled to a volume: the volume its surface encloses, summed by
// one workgroup in a fixed order (triangle j into lane j % 256 in order, then the lanes pairwise,
// halving), and the fill's pressure from it. CPU twins: MassSpring::hold_fill, MassSpring::pressure.

@group(0) @binding(0) var<uniform> sim: SimParams;
@group(0) @binding(1) var<storage, read> pos: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> triangles: array<vec4<u32>>;
@group(0) @binding(3) var<storage, read_write> fill: array<f32>;       // [0]: pressure, [1]: volume, [2]: held pressure

const LANES: u32 = 256u;
var<workgroup> partial: array<f32, 256>;

@compute @workgroup_size(256)
fn main(@builtin(local_invocation_index) lane: u32) {
    var sum = 0.0;
    for (var j = lane; j < sim.tri_count; j += LANES) {
        let t = triangles[j];
        let a = pos[t.x].xyz;
        let b = pos[t.y].xyz;
        let c = pos[t.z].xyz;
        sum += dot3(a, cross3(b, c)) / 6.0;
    }
    partial[lane] = sum;
    workgroupBarrier();
    for (var half = LANES / 2u; half > 0u; half /= 2u) {
        if lane < half {
            partial[lane] += partial[lane + half];
        }
        workgroupBarrier();
    }
    if lane == 0u {
        let v = partial[0];
        // The fill's integral term (CPU twin: MassSpring::hold_fill), then its pressure.
        if sim.fill_hold > 0.0 {
            fill[2] = fill[2] + sim.fill_hold * sim.fill_bulk * ((sim.fill_volume - v) / sim.fill_volume);
        }
        fill[0] = sim.pressure + sim.fill_bulk * (sim.fill_volume - v) / sim.fill_volume + fill[2];
        fill[1] = v;
    }
}
