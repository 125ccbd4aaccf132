// Ceres reference for `scripts/bench/ba_vs_ceres.py`: solves a BAL file the way
// Ceres' own examples/bundle_adjuster.cc does (SnavelyReprojectionError with automatic
// differentiation, every camera and point free, default tolerances, no normalisation or
// perturbation so both solvers see the very same problem) and prints one JSON line.
//
//   ba_ceres FILE [--solver sparse|dense|iterative] [--loss none|huber:A|cauchy:A]
//            [--max-iterations N] [--threads N]
//
// Built by the benchmark script into a temporary directory:
//   g++ -O3 -std=c++17 ba_ceres.cc -I/usr/include/eigen3 -lceres -lglog -o ba_ceres
#include <ceres/ceres.h>
#include <ceres/rotation.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

namespace {

struct SnavelyReprojectionError {
  SnavelyReprojectionError(double x, double y) : observed_x(x), observed_y(y) {}
  template <typename T>
  bool operator()(const T* const camera, const T* const point, T* residuals) const {
    T p[3];
    ceres::AngleAxisRotatePoint(camera, point, p);
    p[0] += camera[3];
    p[1] += camera[4];
    p[2] += camera[5];
    const T xp = -p[0] / p[2];
    const T yp = -p[1] / p[2];
    const T& l1 = camera[7];
    const T& l2 = camera[8];
    const T r2 = xp * xp + yp * yp;
    const T distortion = 1.0 + r2 * (l1 + l2 * r2);
    const T& focal = camera[6];
    residuals[0] = focal * distortion * xp - observed_x;
    residuals[1] = focal * distortion * yp - observed_y;
    return true;
  }
  static ceres::CostFunction* Create(double x, double y) {
    return new ceres::AutoDiffCostFunction<SnavelyReprojectionError, 2, 9, 3>(
        new SnavelyReprojectionError(x, y));
  }
  double observed_x, observed_y;
};

bool read_bal(const char* path, int& nc, int& np, std::vector<int>& cam, std::vector<int>& pt,
              std::vector<double>& obs, std::vector<double>& params) {
  FILE* f = std::fopen(path, "r");
  if (!f) return false;
  int no = 0;
  if (std::fscanf(f, "%d %d %d", &nc, &np, &no) != 3) return false;
  cam.resize(no);
  pt.resize(no);
  obs.resize(2 * no);
  for (int i = 0; i < no; ++i) {
    if (std::fscanf(f, "%d %d %lf %lf", &cam[i], &pt[i], &obs[2 * i], &obs[2 * i + 1]) != 4)
      return false;
  }
  params.resize(9 * nc + 3 * np);
  for (double& v : params) {
    if (std::fscanf(f, "%lf", &v) != 1) return false;
  }
  std::fclose(f);
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  google::InitGoogleLogging(argv[0]);
  FLAGS_minloglevel = 2;  // Ceres' "linear solver failure" warnings are part of normal LM.
  if (argc < 2) {
    std::fprintf(stderr, "usage: ba_ceres FILE [--solver sparse|dense|iterative] [--loss L] "
                         "[--max-iterations N] [--threads N]\n");
    return 2;
  }
  std::string solver = "sparse", loss = "none";
  int max_iterations = 50, threads = 2;
  for (int i = 2; i + 1 < argc; i += 2) {
    if (!std::strcmp(argv[i], "--solver")) solver = argv[i + 1];
    else if (!std::strcmp(argv[i], "--loss")) loss = argv[i + 1];
    else if (!std::strcmp(argv[i], "--max-iterations")) max_iterations = std::atoi(argv[i + 1]);
    else if (!std::strcmp(argv[i], "--threads")) threads = std::atoi(argv[i + 1]);
    else { std::fprintf(stderr, "unknown flag %s\n", argv[i]); return 2; }
  }
  int nc = 0, np = 0;
  std::vector<int> cam, pt;
  std::vector<double> obs, params;
  if (!read_bal(argv[1], nc, np, cam, pt, obs, params)) {
    std::fprintf(stderr, "cannot read %s\n", argv[1]);
    return 1;
  }
  double* cameras = params.data();
  double* points = params.data() + 9 * nc;

  ceres::Problem problem;
  for (size_t i = 0; i < cam.size(); ++i) {
    ceres::LossFunction* lf = nullptr;
    if (loss.rfind("huber", 0) == 0 || loss.rfind("cauchy", 0) == 0) {
      double a = 1.0;
      size_t colon = loss.find(':');
      if (colon != std::string::npos) a = std::atof(loss.c_str() + colon + 1);
      if (loss[0] == 'h') lf = new ceres::HuberLoss(a);
      else lf = new ceres::CauchyLoss(a);
    }
    problem.AddResidualBlock(SnavelyReprojectionError::Create(obs[2 * i], obs[2 * i + 1]), lf,
                             cameras + 9 * cam[i], points + 3 * pt[i]);
  }

  ceres::Solver::Options options;
  options.linear_solver_type = solver == "dense"       ? ceres::DENSE_SCHUR
                               : solver == "iterative" ? ceres::ITERATIVE_SCHUR
                                                       : ceres::SPARSE_SCHUR;
  if (solver == "iterative") options.preconditioner_type = ceres::SCHUR_JACOBI;
  // Points first (eliminated), cameras second, as bundle_adjuster's ordering.
  auto* ordering = new ceres::ParameterBlockOrdering;
  for (int j = 0; j < np; ++j) ordering->AddElementToGroup(points + 3 * j, 0);
  for (int j = 0; j < nc; ++j) ordering->AddElementToGroup(cameras + 9 * j, 1);
  options.linear_solver_ordering.reset(ordering);
  options.max_num_iterations = max_iterations;
  options.num_threads = threads;
  options.minimizer_progress_to_stdout = false;
  options.logging_type = ceres::SILENT;

  ceres::Solver::Summary summary;
  auto t0 = std::chrono::steady_clock::now();
  ceres::Solve(options, &problem, &summary);
  double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

  std::printf("{\"initial_cost\":%.17g,\"final_cost\":%.17g,\"iterations\":%d,\"seconds\":%.6f,"
              "\"observations\":%zu,\"successful_steps\":%d,\"linear_solver\":\"%s\","
              "\"termination\":\"%s\",\"trace\":[",
              summary.initial_cost, summary.final_cost,
              summary.num_successful_steps + summary.num_unsuccessful_steps, seconds, cam.size(),
              summary.num_successful_steps, solver.c_str(),
              ceres::TerminationTypeToString(summary.termination_type));
  // (cumulative seconds since Solve started, cost) after every iteration.
  double offset = seconds - summary.total_time_in_seconds;
  for (size_t i = 0; i < summary.iterations.size(); ++i) {
    const auto& it = summary.iterations[i];
    std::printf("%s[%.6f,%.17g]", i ? "," : "", offset + it.cumulative_time_in_seconds, it.cost);
  }
  std::printf("]}\n");
  return 0;
}
