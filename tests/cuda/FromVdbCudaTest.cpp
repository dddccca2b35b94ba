// from-vdb on the GPU against the CPU (the reference): the round trip of a generated model through
// a to-vdb volume, as tests/job/FromVdbTest.cpp runs it, fitted once with --device cpu and once
// with --device cuda. The moment initialisation and the judge run on the CPU in both; only the
// Stage II engine (VolumeFit over runStageTwo) moves, so counts must agree exactly and the fit's
// errors and energies only as far as float sums in another order let the trajectories drift.
// Skips with a message where cudaGetDeviceCount finds no GPU. The tolerances below are first
// guesses (the Stage II parity tests allow 1e-3 relative on 100-iteration energies); tighten
// them to the worst values seen on a GPU (scripts/cuda-device-check.sh).
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include <unistd.h>

#include "kernels/CudaBackends.h"
#include "CudaTestSupport.h"
#include "job/FromVdb.h"
#include "vdb/SampleGrid.h"
#include "vdb/VdbExport.h"
#include "core/Device.h"
#include "field/FieldTestModels.h"

namespace splatwarp {
namespace {

constexpr double kFitErrorRel = 0.02;  // held-out opacity/colour error after the fit
constexpr double kEnergyRel = 0.02;    // best training energy of the round

FromVdbResult fitOn(const Volume& volume, std::size_t gaussians, Device device)
{
    FromVdbOptions o = defaultFromVdbOptions();
    o.meaning = VolumeMeaning::Field;
    o.gaussians = gaussians;
    o.fitting.iterations = 60;
    o.judge.points = 20000;
    o.samplesPerAxis = 1;
    o.fitting.stage2.device = resolveDevice(device);
    return fromVdb(volume, o);
}

TEST(FromVdbCuda, RoundTripMatchesCpu)
{
    SPLATWARP_REQUIRE_GPU();
    const test::CudaBackendsScope backends;
    const GaussianCloud original = test::randomCloud(60, 1, 7, 1.0f, 0.08f, 0.25f);
    SampleGridOptions go;
    go.cells = 12;
    const SampleGrid grid(original, go);
    const std::filesystem::path file =
        std::filesystem::temp_directory_path() / ("splatwarp-fromvdb-cuda-" + std::to_string(::getpid()) + ".vdb");
    VdbExportOptions vo;
    vo.shGrids = true;
    writeSampleGridVdb(file.string(), grid, vo);
    const Volume volume = readVolume(file.string());

    const FromVdbResult cpu = fitOn(volume, original.size(), Device::Cpu);
    const FromVdbResult gpu = fitOn(volume, original.size(), Device::Cuda);
    ASSERT_EQ(gpu.report["fit"]["rounds"].size(), cpu.report["fit"]["rounds"].size());
    for (std::size_t k = 0; k < cpu.report["fit"]["rounds"].size(); ++k) {
        const nlohmann::json &c = cpu.report["fit"]["rounds"][k], &g = gpu.report["fit"]["rounds"][k];
        EXPECT_EQ(c["device"], "cpu");
        EXPECT_EQ(g["device"], "cuda");
        EXPECT_EQ(g["samplesUsed"], c["samplesUsed"]);
        const double ec = c["energyBest"], eg = g["energyBest"];
        EXPECT_NEAR(eg, ec, kEnergyRel * ec) << "round " << k;
    }
    EXPECT_EQ(gpu.splats.size(), cpu.splats.size());
    for (const char* what : {"opacity", "color"}) {
        const double ec = cpu.report["heldOut"]["fit"][what], eg = gpu.report["heldOut"]["fit"][what];
        EXPECT_NEAR(eg, ec, kFitErrorRel * ec) << what << ": cpu " << ec << " cuda " << eg;
        RecordProperty(std::string("fit_error_") + what + "_cuda", std::to_string(eg));
    }
    // The fit still does its job on the GPU.
    const double before = gpu.report["heldOut"]["noFit"]["opacity"], after = gpu.report["heldOut"]["fit"]["opacity"];
    EXPECT_LT(after, before);
    std::filesystem::remove(file);
}

} // namespace
} // namespace splatwarp
