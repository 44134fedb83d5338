#include "fillgs/experiment/rigs.hpp"

#include <Eigen/Dense>
#include <cstdio>

#include "fillgs/base/error.hpp"

namespace fillgs {

const std::vector<ColmapPose>& n3v_rig_poses() {
  // ../shared/data/video/n3v_flame_steak_frame0/sparse/0/images.bin (Neural 3D Video
  // flame_steak; COLMAP model from the 3DGStream repository's test data), printed with 17
  // significant digits. tests/test_synth.cpp compares this table with the file.
  static const std::vector<ColmapPose> poses = {
    {"cam00", {0.99891810100076039, 0.029722135195175577, 0.03446073174847937, -0.0095749746649254012}, {0.0088287504842917072, 1.30169684981265, 0.35343499096919812}},
    {"cam01", {0.94282230913980902, 0.026416694387861088, 0.33171888486645423, -0.018730538402646778}, {-4.70938131340744, 1.2961529717363496, 1.8950567695842981}},
    {"cam02", {0.96094668066779187, 0.029771854054638423, 0.27482920355054141, -0.012807126745581284}, {-3.9375065850807571, 1.2646690872758641, 1.5173039166673326}},
    {"cam03", {0.97667339927455932, 0.023894037862863069, 0.21327569023679696, -0.0071851275634596317}, {-2.9214889903607659, 1.2582081903754665, 1.5153609195958631}},
    {"cam04", {0.98900889331605391, 0.016364357751055599, 0.14694766194973224, -3.7210980094592742e-05}, {-2.0686188034486834, 1.2458686735463207, 0.89771926846376537}},
    {"cam05", {0.99507813393769928, 0.018228555026547275, 0.097398462777412806, -0.00087555085945657969}, {-1.0566193218017528, 1.2783031008177828, 0.50241336960024685}},
    {"cam06", {0.99929423017453045, 0.017937603189998985, -0.032980342760723952, 0.0012573476353194384}, {1.0047952786504113, 1.3370345922252411, 0.45790693992015435}},
    {"cam07", {0.99492184919195015, 0.02526026470204485, -0.097232575811696753, 0.0061854044876333784}, {1.9639055214052705, 1.3444625293270169, 0.86872015058200325}},
    {"cam08", {0.98783891754857012, 0.029324738743460955, -0.15269025235702613, -0.00013967549887021629}, {2.8912877487442814, 1.3266899956090548, 1.4867046713565975}},
    {"cam09", {0.97475999122755541, 0.028565439374013322, -0.22113994791688266, 0.011139955598837566}, {3.8446712407285162, 1.3633638147640035, 1.4518905721967321}},
    {"cam10", {0.95817162567430303, 0.033210731784607095, -0.28399592336450524, 0.012267785429182979}, {4.5996810502042651, 1.3882155375923368, 1.8551349827149102}},
    {"cam11", {0.98950720224248556, -0.045418497508445101, 0.13705129476509109, 0.0054405328356960684}, {-5.6540810646543767, -1.619631627082962, 0.70484323680291683}},
    {"cam12", {0.99629239621191534, -0.0062315164058024267, 0.080962288341037511, 0.02842071990972455}, {-4.6306851246698111, -1.81280242497184, 0.055558525848173855}},
    {"cam13", {0.98305711272897311, 0.0038288149084579354, 0.18185617649249405, 0.022635908660858409}, {-2.5155018542241594, -1.6378900351742449, 1.2287077088385332}},
    {"cam14", {0.99134942521542446, -0.017928966688738109, 0.12914519834569677, 0.015046163058153003}, {-1.3891730711586927, -1.4979516108556898, 0.80598025202427226}},
    {"cam15", {0.99849309039495615, -0.022639474589332406, 0.049964272539703668, 0.0016043981510866741}, {-0.45691385776758198, -1.4483648248376284, 0.53818642150769203}},
    {"cam16", {0.99999983957325411, -0.00022492759132151466, 0.00051748759918639263, -4.9675240186906532e-05}, {0.61770578656978514, -1.4302639915925186, 0.49482362546899439}},
    {"cam17", {0.99655322157592618, -0.015272328150701453, -0.076502899322841711, 0.028208845327300978}, {1.7205048555212816, -1.2877350253283948, 0.8760874343111511}},
    {"cam18", {0.99114812295060717, -0.006529783488336308, -0.12944209792935954, 0.028766362000256049}, {2.6834259589122813, -1.1913744576787197, 1.3911647957759126}},
    {"cam19", {0.99296555344273596, -0.067208107431545996, -0.096278651911486005, 0.015261099493086369}, {4.7521361978564194, -1.1589262753743816, 0.95851764578645238}},
    {"cam20", {0.98034218345577984, -0.098200730159254665, -0.16616466630788657, 0.040928273896317917}, {5.6324861760590164, -0.738150043159017, 1.7370945246331591}},
  };
  return poses;
}

PinholeIntrinsics n3v_rig_intrinsics() {
  // cameras.bin of the same model: camera 1, PINHOLE.
  return {2690, 2016, 1460.6432563436313, 1455.0342281127766, 1345.0, 1008.0};
}

std::vector<Camera> n3v_rig_colmap(int width, int height) {
  const PinholeIntrinsics k = n3v_rig_intrinsics();
  const double sx = double(width) / k.width, sy = double(height) / k.height;
  std::vector<Camera> cams;
  for (const ColmapPose& p : n3v_rig_poses()) {
    Camera c;
    c.name = p.name;
    c.width = width;
    c.height = height;
    c.fx = k.fx * sx;
    c.fy = k.fy * sy;
    c.cx = k.cx * sx;
    c.cy = k.cy * sy;
    c.R = quat_to_matrix<double>(Vec4d(p.q[0], p.q[1], p.q[2], p.q[3]).normalized());
    c.t = Vec3d(p.t[0], p.t[1], p.t[2]);
    cams.push_back(c);
  }
  return cams;
}

Vec3d convergence_point(const std::vector<Camera>& cams) {
  FILLGS_CHECK(cams.size() >= 2);
  Mat3d A = Mat3d::Zero();
  Vec3d b = Vec3d::Zero();
  for (const Camera& c : cams) {
    const Vec3d f = c.R.row(2).transpose().normalized();  // optical axis in world
    const Mat3d P = Mat3d::Identity() - f * f.transpose();
    A += P;
    b += P * c.centre();
  }
  return A.ldlt().solve(b);
}

std::vector<Camera> placed_rig(const std::vector<Camera>& cams, double s, const Vec3d& target) {
  Mat3d A;  // (x, y, z) -> (x, z, -y): y down / z forward to z up / y forward
  A << 1, 0, 0, 0, 0, 1, 0, -1, 0;
  const Vec3d c = convergence_point(cams);
  std::vector<Camera> out;
  for (Camera cam : cams) {
    // x_cam = R x + t with x = Aᵀ(x' − target)/s + c  ⇒  metric x_cam·s = R Aᵀ x' + s·t + R(s·c − Aᵀ target).
    const Mat3d R = cam.R * A.transpose();
    const Vec3d t = s * cam.t + cam.R * (s * c) - R * target;
    cam.R = R;
    cam.t = t;
    out.push_back(cam);
  }
  return out;
}

std::vector<Camera> technicolor_rig(int width, int height, double spacing, const Vec3d& centre, double fov_x) {
  std::vector<Camera> cams;
  for (int row = 0; row < 4; ++row)
    for (int col = 0; col < 4; ++col) {
      Camera c;
      char name[16];
      std::snprintf(name, sizeof name, "cam%02d", row * 4 + col);
      c.name = name;
      c.set_fov_x(fov_x, width, height);
      const Vec3d eye = centre + Vec3d((col - 1.5) * spacing, 0.0, (1.5 - row) * spacing);
      c.look_at(eye, eye + Vec3d(0, 1, 0), Vec3d(0, 0, 1));
      cams.push_back(c);
    }
  return cams;
}

}  // namespace fillgs
