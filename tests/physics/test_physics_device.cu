// The physics headers compiled for the device: stresses, transfers and boundaries on the GPU equal the host's.
#include <cuda_runtime.h>
#include <gtest/gtest.h>

#include <vector>

#include "MnSystem/Cuda/device_query.h"
#include "physics/boundary.cuh"
#include "physics/constitutive_models.cuh"
#include "physics/grid_update.cuh"
#include "physics_test_support.h"
#include "physics/time_step.cuh"
#include "physics/transfer.cuh"

namespace fbar {
namespace {

struct DeviceCase {
  Mat3f F;
  float one_minus_J;
  Vec3f x;
  Vec3f v;
};
struct DeviceOut {
  Mat3f tau_solid;
  Mat3f tau_fluid;
  float c_fluid;
  Vec3f momentum_sum;
  Vec3f v_wall;
  float dt;
};

FBAR_HOST_DEVICE DeviceOut evaluate(const DeviceCase& in, const FixedCorotatedParams<float>& ps,
                                    const JFluidParams<float>& pf, const BoundaryParams<float>& wall) {
  DeviceOut out{};
  Mat3f C = Mat3f::zero();
  C(0, 1) = 2.0f;
  out.tau_solid = FixedCorotated::kirchhoff_stress(ps, FixedCorotatedState<float>{in.F}, C).kirchhoff;
  out.tau_fluid = JFluid::kirchhoff_stress(pf, JFluidState<float>{in.one_minus_J}, C).kirchhoff;
  out.c_fluid = JFluid::wave_speed(pf, JFluidState<float>{in.one_minus_J});
  const float dx = 0.1f;
  const auto s = quadratic_bspline(in.x, dx);
  const auto payload = mls_p2g_particle(1.0f, 1e-3f, in.v, C, out.tau_solid, 1e-4f, apic_inertia_inverse(dx));
  Vec3f sum = Vec3f::zero();
  for_each_stencil_node(s, dx,
                        [&](int, int, int, float w, const Vec3f& d) { sum += p2g_node_momentum(payload, w, d); });
  out.momentum_sum = sum;
  const Vec3f v = grid_node_velocity(2.0f, in.v, Vec3f{{0.0f, -9.81f, 0.0f}}, 1e-3f);
  out.v_wall = apply_boundary(wall, Vec3f{{0.5f, 0.1f, 0.5f}}, v);
  out.dt = cfl_time_step(0.5f, dx, out.c_fluid, 3.0f);
  return out;
}

__global__ void evaluate_kernel(const DeviceCase* in, DeviceOut* out, int n, FixedCorotatedParams<float> ps,
                                JFluidParams<float> pf, BoundaryParams<float> wall) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i < n) out[i] = evaluate(in[i], ps, pf, wall);
}

// Device math (rsqrt in the SVD, expm1/log1p) differs from glibc by an ulp or two: float tolerance 1e-5 relative to
// the stress scale.
TEST(PhysicsDevice, MatchesHost) {
  if (cuda::device_count() == 0) GTEST_SKIP() << "no CUDA device: " << cuda::no_device_reason();
  MaterialSpec solid;
  solid.youngs_modulus = 1e7;
  solid.poisson_ratio = 0.3;
  MaterialSpec fluid;
  fluid.bulk_modulus = 2e8;
  fluid.gamma = 7.125f;
  fluid.viscosity = 1e-3;
  const auto ps = FixedCorotated::make_params<float>(solid);
  const auto pf = JFluid::make_params<float>(fluid);
  BoundarySpec spec;
  spec.contact = Contact::Separable;
  SimulationSpec sim;
  sim.dx = 0.1;
  BoundaryParams<float> wall{};
  std::string error;
  ASSERT_TRUE(make_boundary_params(spec, sim.dx, sim.domain, wall, error));

  std::mt19937_64 rng(5);
  std::vector<DeviceCase> cases;
  for (int n = 0; n < 256; ++n) {
    const Mat3d F = test::random_deformation(rng, 0.3);
    cases.push_back(DeviceCase{F.cast<float>(), 1e-6f * static_cast<float>(n - 128),
                               Vec3f{{0.31f + 0.001f * n, 0.52f, 0.77f}}, Vec3f{{1.0f, -2.0f, 0.5f}}});
  }
  DeviceCase* d_in = nullptr;
  DeviceOut* d_out = nullptr;
  const int n = static_cast<int>(cases.size());
  FBAR_CUDA_CHECK(cudaMalloc(&d_in, n * sizeof(DeviceCase)));
  FBAR_CUDA_CHECK(cudaMalloc(&d_out, n * sizeof(DeviceOut)));
  FBAR_CUDA_CHECK(cudaMemcpy(d_in, cases.data(), n * sizeof(DeviceCase), cudaMemcpyHostToDevice));
  evaluate_kernel<<<(n + 63) / 64, 64>>>(d_in, d_out, n, ps, pf, wall);
  FBAR_CUDA_CHECK(cudaGetLastError());
  std::vector<DeviceOut> out(n);
  FBAR_CUDA_CHECK(cudaMemcpy(out.data(), d_out, n * sizeof(DeviceOut), cudaMemcpyDeviceToHost));
  FBAR_CUDA_CHECK(cudaFree(d_in));
  FBAR_CUDA_CHECK(cudaFree(d_out));
  const float scale = ps.lambda + 2 * ps.mu;
  for (int i = 0; i < n; ++i) {
    const DeviceOut h = evaluate(cases[i], ps, pf, wall);
    EXPECT_LE(max_abs(out[i].tau_solid - h.tau_solid), 1e-5f * scale) << i;
    const float pscale = std::max(1e-6f * pf.bulk_modulus, max_abs(h.tau_fluid));
    EXPECT_LE(max_abs(out[i].tau_fluid - h.tau_fluid), 1e-5f * pscale) << i;
    EXPECT_NEAR(out[i].c_fluid, h.c_fluid, 1e-5f * h.c_fluid);
    EXPECT_LE(max_abs(out[i].momentum_sum - h.momentum_sum), 1e-4f) << i;
    EXPECT_EQ(out[i].v_wall, h.v_wall);
    EXPECT_NEAR(out[i].dt, h.dt, 1e-5f * h.dt);
  }
}

}  // namespace
}  // namespace fbar
