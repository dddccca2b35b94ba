/// `splatwarp bench edit [MODEL]`: the editor's POST /api/pose round trip over loopback for a
/// sequence of gizmo-like poses (a drag turning the +x end about z), p50 and p95.
#include <algorithm>
#include <cstdio>
#include <httplib.h>
#include <nlohmann/json.hpp>

#include "Command.h"
#include "ReadArgs.h"
#include "SharedArgs.h"
#include "core/Error.h"
#include "core/Progress.h"
#include "edit/DragSpec.h"
#include "edit/EditServer.h"

namespace splatwarp::cli {
namespace {

struct BenchEditArgs {
    std::string input;
    bool dropInvalid = false;
    int poses = 100;
    int nodes = 0;
    bool json = false;
    Device device = Device::Auto;
};

double percentile(std::vector<double> v, double p)
{
    std::sort(v.begin(), v.end());
    const double at = p * double(v.size() - 1);
    const std::size_t i = std::size_t(at);
    return i + 1 < v.size() ? v[i] + (at - double(i)) * (v[i + 1] - v[i]) : v.back();
}

double headerMs(const httplib::Result& r, const char* name) { return std::atof(r->get_header_value(name).c_str()); }

void runBench(const BenchEditArgs& a)
{
    edit::EditServerOptions options;
    options.job.input = a.input;
    options.job.dropInvalid = a.dropInvalid;
    options.job.stage1Only = true; // the pose round trip needs no sample grid
    options.job.evaluate = false;
    options.job.device = a.device;
    if (a.nodes > 0) options.job.nodes = a.nodes;
    const bool quiet = !progressEnabled();
    setProgressEnabled(false);
    edit::EditServer server(options);
    const int port = server.start();
    httplib::Client client("127.0.0.1", port);
    client.set_default_headers({{"Authorization", "Bearer " + server.token()}});
    client.set_read_timeout(60, 0);
    std::vector<double> roundMs, solveMs, updateMs, encodeMs;
    std::size_t bytes = 0;
    for (int i = -1; i < a.poses; ++i) { // pose -1 warms up (first allocation of the result)
        // Pose i of n turns the +x end by up to 90 degrees in small steps, as a gizmo drag sends them.
        const std::string body = edit::bendDragSpec(90.0 * double(std::max(i, 0) + 1) / double(a.poses));
        const Stopwatch clock;
        const httplib::Result r = client.Post("/api/pose", body, "application/json");
        const double ms = clock.ms();
        if (!r || r->status != 200) throw IoError(msg("bench edit: POST /api/pose failed: ", r ? r->body : httplib::to_string(r.error())));
        if (i < 0) continue;
        roundMs.push_back(ms);
        solveMs.push_back(headerMs(r, "X-Splatwarp-Solve-Ms"));
        updateMs.push_back(headerMs(r, "X-Splatwarp-Update-Ms"));
        encodeMs.push_back(headerMs(r, "X-Splatwarp-Encode-Ms"));
        bytes = r->body.size();
    }
    server.stop();
    setProgressEnabled(!quiet);
    const nlohmann::json j = {{"model", a.input}, {"poses", a.poses}, {"replyBytes", bytes},
                              {"roundTripMs", {{"p50", percentile(roundMs, 0.5)}, {"p95", percentile(roundMs, 0.95)}}},
                              {"serverMedianMs", {{"solve", percentile(solveMs, 0.5)}, {"update", percentile(updateMs, 0.5)},
                                                  {"encode", percentile(encodeMs, 0.5)}}}};
    if (a.json) {
        std::printf("%s\n", j.dump(2).c_str());
        return;
    }
    std::printf("edit benchmark: %s, %d poses over loopback, %zu bytes per reply\n", a.input.c_str(), a.poses, bytes);
    std::printf("POST /api/pose round trip: p50 %.1f ms, p95 %.1f ms (server medians: ED solve %.1f, Stage I update %.1f, encode %.1f)\n",
                percentile(roundMs, 0.5), percentile(roundMs, 0.95), percentile(solveMs, 0.5), percentile(updateMs, 0.5),
                percentile(encodeMs, 0.5));
}

const CommandRegistrar reg(1060, [](CLI::App& app) {
    auto args = std::make_shared<BenchEditArgs>();
    CLI::App* sub = benchCommand(app)->add_subcommand(
        "edit", "Time the editor's POST /api/pose round trip over loopback (a gizmo drag of poses): p50, p95");
    sub->add_option("input", args->input, "Model to edit")->required()->check(CLI::ExistingFile);
    addDropInvalidFlag(sub, args->dropInvalid);
    sub->add_option("--poses", args->poses, "Poses in the drag")->check(inRange(1, 100000))->capture_default_str();
    sub->add_option("--nodes", args->nodes, "Graph node count (default: the spec default, 256)")->check(positive());
    sub->add_flag("--json", args->json, "Print JSON instead of a line");
    addDeviceOption(sub, args->device, "Stage I's update runs");
    sub->callback([args] { runBench(*args); });
});

} // namespace
} // namespace splatwarp::cli
