#include "engine/volume_export.hpp"

#include <sstream>

#include "physics/corotational.hpp"

namespace lumen::engine {

namespace {

// Significant digits of every exported real (round-trips a double exactly).
constexpr int kDigits = 17;

// The tet's rest corners and displacements (4 x 3 each, metres).
void element_of(const Model& model, const Eigen::VectorXd& u, int t, Eigen::Matrix<double, 4, 3>& X,
                Eigen::Matrix<double, 4, 3>& ue) {
  for (int k = 0; k < 4; ++k) {
    const int node = model.mesh.tets(t, k);
    X.row(k) = model.mesh.rest.row(node);
    ue.row(k) = u.segment<3>(3 * node).transpose();
  }
}

// One DataArray of rows x components reals (row-major), one row per line.
void real_array(std::ostringstream& out, const char* name, const double* data, long rows, int components) {
  out << "        <DataArray type=\"Float64\" Name=\"" << name << "\" NumberOfComponents=\"" << components
      << "\" format=\"ascii\">\n";
  for (long r = 0; r < rows; ++r) {
    out << "         ";
    for (int c = 0; c < components; ++c) out << ' ' << data[r * components + c];
    out << '\n';
  }
  out << "        </DataArray>\n";
}

// The cells: connectivity, offsets and types of the model's linear tets.
void cells(std::ostringstream& out, const Tets& tets) {
  out << "      <Cells>\n        <DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">\n";
  for (int t = 0; t < tets.rows(); ++t)
    out << "          " << tets(t, 0) << ' ' << tets(t, 1) << ' ' << tets(t, 2) << ' ' << tets(t, 3) << '\n';
  out << "        </DataArray>\n        <DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">\n";
  for (int t = 0; t < tets.rows(); ++t) out << "          " << 4L * (t + 1) << '\n';
  out << "        </DataArray>\n        <DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">\n";
  for (int t = 0; t < tets.rows(); ++t) out << "          " << kVtkTetra << '\n';
  out << "        </DataArray>\n      </Cells>\n";
}

}  // namespace

Eigen::VectorXd tet_von_mises(const Model& model, const Eigen::VectorXd& u, const physics::LinearMaterial& material) {
  const Tets& tets = model.mesh.tets;
  Eigen::VectorXd vm(tets.rows());
  Eigen::Matrix<double, 4, 3> X, ue;
  for (int t = 0; t < tets.rows(); ++t) {
    element_of(model, u, t, X, ue);
    const Eigen::Matrix3d H = physics::tet_displacement_gradient(X, ue);
    Eigen::Matrix3d eps = 0.5 * (H + H.transpose());
    // Corotational: the strain of F with its rotation taken out.
    if (model.material == MaterialModel::kCorotational) {
      const Eigen::Matrix3d F = Eigen::Matrix3d::Identity() + H;
      const Eigen::Matrix3d S = physics::proper_rotation(F).transpose() * F;
      eps = 0.5 * (S + S.transpose()) - Eigen::Matrix3d::Identity();
    }
    vm(t) = physics::von_mises(physics::linear_stress(eps, material));
  }
  return vm;
}

std::string volume_vtu(const Model& model, const State& state, const physics::LinearMaterial& material) {
  const long n = model.mesh.n_nodes();
  const Points displacement = state.x - model.mesh.rest;  // n x 3, metres
  const Eigen::VectorXd u = Eigen::Map<const Eigen::VectorXd>(displacement.data(), displacement.size());
  const Eigen::VectorXd vm = tet_von_mises(model, u, material);
  std::ostringstream out;
  out.precision(kDigits);
  out << "<?xml version=\"1.0\"?>\n"
      << "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\">\n"
      << "  <UnstructuredGrid>\n    <Piece NumberOfPoints=\"" << n << "\" NumberOfCells=\"" << model.mesh.tets.rows()
      << "\">\n      <Points>\n";
  real_array(out, "positions", state.x.data(), n, 3);
  out << "      </Points>\n";
  cells(out, model.mesh.tets);
  // Point data: displacement from rest and the contact flag.
  out << "      <PointData Vectors=\"displacement\" Scalars=\"contact\">\n";
  real_array(out, "displacement", displacement.data(), n, 3);
  out << "        <DataArray type=\"UInt8\" Name=\"contact\" format=\"ascii\">\n";
  for (long i = 0; i < n; ++i) out << "          " << (state.in_contact[i] ? 1 : 0) << '\n';
  out << "        </DataArray>\n      </PointData>\n      <CellData Scalars=\"von_mises\">\n";
  real_array(out, "von_mises", vm.data(), vm.size(), 1);
  out << "      </CellData>\n    </Piece>\n  </UnstructuredGrid>\n</VTKFile>\n";
  return out.str();
}

std::string volume_pvd(const std::vector<std::pair<double, std::string>>& frames) {
  std::ostringstream out;
  out.precision(kDigits);
  out << "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">\n"
      << "  <Collection>\n";
  for (const auto& [t, file] : frames)
    out << "    <DataSet timestep=\"" << t << "\" group=\"\" part=\"0\" file=\"" << file << "\"/>\n";
  out << "  </Collection>\n</VTKFile>\n";
  return out.str();
}

}  // namespace lumen::engine
