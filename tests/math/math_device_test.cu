// Device parity for MnBase/Math: svd, symmetric_eigen, polar_decomposition and quadratic_bspline run in CUDA kernels
// meet the same accuracy bounds as on the host (the device path uses the hardware rsqrt and FMA contraction, so
// results are compared by their error bounds, not bit for bit). Skips with the reason when there is no GPU.
#include <cuda_runtime.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "MnBase/Math/bspline.h"
#include "MnBase/Math/svd.h"
#include "MnSystem/Cuda/device_query.h"

namespace fbar {
namespace {

template <typename T>
struct DecompositionResult {
  Svd3<T> svd;
  SymEig3<T> eig;
  Polar3<T> polar;
};

template <typename T>
__global__ void decompose_kernel(const Mat3<T>* a, DecompositionResult<T>* out, int n) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= n) return;
  const Mat3<T> m = a[i];
  out[i].svd = svd(m);
  out[i].eig = symmetric_eigen(T(0.5) * (m + transpose(m)));
  out[i].polar = polar_decomposition(m);
}

template <typename T>
__global__ void bspline_kernel(const Vec3<T>* x, T dx, QuadraticBspline<T>* out, int n) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i < n) out[i] = quadratic_bspline(x[i], dx);
}

/// Minimal owning device array for the test.
template <typename T>
class DeviceArray {
 public:
  explicit DeviceArray(std::size_t n) : n_(n) { FBAR_CUDA_CHECK(cudaMalloc(&p_, n * sizeof(T))); }
  ~DeviceArray() { cudaFree(p_); }
  DeviceArray(const DeviceArray&) = delete;
  DeviceArray& operator=(const DeviceArray&) = delete;
  T* get() { return p_; }
  void upload(const std::vector<T>& h) {
    FBAR_CUDA_CHECK(cudaMemcpy(p_, h.data(), n_ * sizeof(T), cudaMemcpyHostToDevice));
  }
  std::vector<T> download() const {
    std::vector<T> h(n_);
    FBAR_CUDA_CHECK(cudaMemcpy(h.data(), p_, n_ * sizeof(T), cudaMemcpyDeviceToHost));
    return h;
  }

 private:
  T* p_ = nullptr;
  std::size_t n_;
};

Mat3d random_rotation(std::mt19937_64& rng) {
  std::normal_distribution<double> g(0.0, 1.0);
  double q[4] = {g(rng), g(rng), g(rng), g(rng)};
  const double n = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  for (double& c : q) c /= n;
  const double w = q[0], x = q[1], y = q[2], z = q[3];
  return Mat3d{{{1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)},
                {2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)},
                {2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)}}};
}

/// Random matrices plus rotations around repeated, clustered, rank-deficient and inverted spectra at scales
/// 1e-20..1e20 (the structured part of the host adversarial list, without Eigen).
std::vector<Mat3d> test_matrices() {
  std::mt19937_64 rng(606);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<Mat3d> ms;
  for (int n = 0; n < 20000; ++n) {
    Mat3d m{};
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) m(i, j) = u(rng);
    ms.push_back(m);
  }
  const double sets[][3] = {{1, 1, 1},       {2, 2, 1},         {1, 1, 0},
                            {1, 0, 0},       {0, 0, 0},         {3, 2, -1},
                            {1, 1, -1},      {1, 1e-8, 1e-16},  {1, 1 + 1e-9, 1 - 1e-9},
                            {1, 1e-4, 1e-8}, {1, 1e-12, -1e-12}};
  for (const auto& s : sets)
    for (int k = 0; k < 200; ++k) {
      const double scale = std::pow(10.0, 10 * (k % 5) - 20);
      ms.push_back(random_rotation(rng) * Mat3d::diagonal(Vec3d{{s[0], s[1], s[2]}}) * random_rotation(rng) * scale);
    }
  return ms;
}

template <typename T>
class MathDevice : public ::testing::Test {
 protected:
  void SetUp() override {
    if (cuda::device_count() == 0) GTEST_SKIP() << cuda::no_device_reason();
  }
};
using Scalars = ::testing::Types<float, double>;
TYPED_TEST_SUITE(MathDevice, Scalars);

TYPED_TEST(MathDevice, DecompositionsMeetHostBounds) {
  using T = TypeParam;
  // Same bound as tests/math/svd_test.cpp: 4 eps per plane rotation, 3 rotations per sweep plus 2 steps for U.
  // The device rsqrt (float: 2 ulp) is within the 4 eps per rotation.
  const double eps = std::numeric_limits<T>::epsilon();
  const double tol = 4.0 * eps * (3 * JacobiSweeps<T>::value + 2);

  std::vector<Mat3<T>> host;
  for (const Mat3d& m : test_matrices()) host.push_back(m.cast<T>());
  const int n = static_cast<int>(host.size());
  DeviceArray<Mat3<T>> d_in(n);
  DeviceArray<DecompositionResult<T>> d_out(n);
  d_in.upload(host);
  decompose_kernel<<<(n + 127) / 128, 128>>>(d_in.get(), d_out.get(), n);
  FBAR_CUDA_CHECK(cudaGetLastError());
  FBAR_CUDA_CHECK(cudaDeviceSynchronize());
  const std::vector<DecompositionResult<T>> out = d_out.download();

  double worst_recon = 0, worst_orth = 0, worst_sigma = 0, worst_eig = 0, worst_polar = 0;
  for (int i = 0; i < n; ++i) {
    SCOPED_TRACE(::testing::Message() << "matrix #" << i);
    const Mat3d a = host[i].template cast<double>();
    const double na = std::max(frobenius_norm(a), std::numeric_limits<double>::min());
    const Svd3<T>& s = out[i].svd;
    const Mat3d u = s.U.template cast<double>(), v = s.V.template cast<double>();
    const double recon = frobenius_norm(u_diag_vt(u, s.sigma.template cast<double>(), v) - a) / na;
    const double orth = std::max(frobenius_norm(transpose(u) * u - Mat3d::identity()),
                                 frobenius_norm(transpose(v) * v - Mat3d::identity()));
    EXPECT_LE(recon, tol);
    EXPECT_LE(orth, tol);
    EXPECT_NEAR(determinant(u), 1.0, tol);
    EXPECT_NEAR(determinant(v), 1.0, tol);
    EXPECT_GE(s.sigma[0], s.sigma[1]);
    EXPECT_GE(s.sigma[1], std::abs(s.sigma[2]));
    // Host and device are both backward stable: by Weyl their singular values differ by at most twice the bound.
    const Svd3<T> h = svd(host[i]);
    double sigma_err = 0;
    for (int k = 0; k < 3; ++k) sigma_err = std::max(sigma_err, std::abs(double(s.sigma[k]) - double(h.sigma[k])) / na);
    EXPECT_LE(sigma_err, 6.0 * tol);

    const Mat3d sym = (a + transpose(a)) * 0.5;
    const SymEig3<T>& e = out[i].eig;
    const Mat3d q = e.Q.template cast<double>();
    const double eig_res = frobenius_norm(sym * q - q * Mat3d::diagonal(e.lambda.template cast<double>())) / na;
    EXPECT_LE(eig_res, tol);
    EXPECT_GE(e.lambda[0], e.lambda[1]);
    EXPECT_GE(e.lambda[1], e.lambda[2]);

    const Polar3<T>& p = out[i].polar;
    const double polar_recon = frobenius_norm(p.R.template cast<double>() * p.S.template cast<double>() - a) / na;
    EXPECT_LE(polar_recon, 2.0 * tol);

    worst_recon = std::max(worst_recon, recon);
    worst_orth = std::max(worst_orth, orth);
    worst_sigma = std::max(worst_sigma, sigma_err);
    worst_eig = std::max(worst_eig, eig_res);
    worst_polar = std::max(worst_polar, polar_recon);
    if (::testing::Test::HasFailure()) break;
  }
  std::printf(
      "[ worst    ] device %s (%d matrices): svd reconstruction %.3g  orthogonality %.3g  |sigma_dev - "
      "sigma_host| %.3g  eigen residual %.3g  polar reconstruction %.3g\n",
      sizeof(T) == 4 ? "float" : "double", n, worst_recon, worst_orth, worst_sigma, worst_eig, worst_polar);
}

TYPED_TEST(MathDevice, BsplineMatchesHost) {
  // Same formulas on both sides; FMA contraction on the device changes the last bits of fx-derived terms only:
  // 8 eps (1 + |x / dx|) per weight.
  using T = TypeParam;
  const double eps = std::numeric_limits<T>::epsilon();
  const T dx = T(0.37);
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> cells(-100.0, 100.0);
  std::vector<Vec3<T>> xs;
  for (int i = 0; i < 10000; ++i) xs.push_back(Vec3<T>{{T(cells(rng) * dx), T(cells(rng) * dx), T(cells(rng) * dx)}});
  for (int i = -3; i <= 3; ++i) xs.push_back(Vec3<T>{{T(i) * dx, (T(i) + T(0.5)) * dx, T(0)}});
  const int n = static_cast<int>(xs.size());
  DeviceArray<Vec3<T>> d_x(n);
  DeviceArray<QuadraticBspline<T>> d_s(n);
  d_x.upload(xs);
  bspline_kernel<<<(n + 127) / 128, 128>>>(d_x.get(), dx, d_s.get(), n);
  FBAR_CUDA_CHECK(cudaGetLastError());
  FBAR_CUDA_CHECK(cudaDeviceSynchronize());
  const std::vector<QuadraticBspline<T>> dev = d_s.download();
  for (int i = 0; i < n; ++i) {
    const QuadraticBspline<T> h = quadratic_bspline(xs[i], dx);
    const double tol = 8 * eps * (1 + 100);
    for (int a = 0; a < 3; ++a) {
      ASSERT_EQ(dev[i].base[a], h.base[a]) << "particle " << i;
      for (int m = 0; m < 3; ++m) {
        EXPECT_NEAR(dev[i].w[a][m], h.w[a][m], tol);
        EXPECT_NEAR(dev[i].dw[a][m] * dx, h.dw[a][m] * dx, tol);
      }
    }
  }
}

}  // namespace
}  // namespace fbar
