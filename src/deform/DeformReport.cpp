#include "deform/DeformReport.h"

namespace splatwarp {

namespace {

nlohmann::json energiesJson(const EdEnergies& e)
{
    return {{"rot", e.rot}, {"reg", e.reg}, {"con", e.con}, {"total", e.total()}};
}

} // namespace

nlohmann::json stageOneReportJson(const Deformation& d, const StageOneResult& s, const GraphOptions& g,
                                  const EdOptions& o)
{
    const DeformationReport& r = d.report;
    nlohmann::json reassign = nlohmann::json::array();
    for (const NodeReassignment& a : r.reassignments)
        reassign.push_back({{"node", a.node}, {"fromHandle", a.fromHandle}, {"toHandle", a.toHandle}});
    std::size_t movingNodes = 0;
    for (std::uint8_t m : d.nodeMoving) movingNodes += m;
    nlohmann::json j;
    j["graph"] = {{"nodes", d.graph.nodeCount()}, {"requestedNodes", g.nodes}, {"k", d.graph.k()}, {"seed", g.seed},
                  {"movingNodes", movingNodes}};
    j["handles"] = {{"nodesPerHandle", r.nodesPerHandle}, {"fixedNodes", r.fixedNodes}, {"targetNodes", r.targetNodes},
                    {"freeNodes", r.freeNodes}, {"reassignments", reassign},
                    {"residualMax", r.residualMax}, {"residualMean", r.residualMean}};
    j["solver"] = {{"iterations", r.solver.iterations}, {"converged", r.solver.converged},
                   {"energiesUnits", "weighted, positions normalised by the node bounding box's largest extent"},
                   {"initial", energiesJson(r.solver.initial)}, {"final", energiesJson(r.solver.final)},
                   {"weights", {{"rot", o.rotWeight}, {"reg", o.regWeight}, {"con", o.conWeight}}}};
    j["stage1"] = {{"gaussians", s.moving.size()}, {"moving", s.movingCount},
                   {"static", s.moving.size() - s.movingCount}, {"device", deviceName(s.device)}};
    j["timingsMs"] = {{"graph", r.graphMs}, {"resolve", r.resolveMs}, {"solve", r.solver.ms},
                      {"weights", s.timings.rigMs}, {"update", s.timings.updateMs}};
    return j;
}

} // namespace splatwarp
