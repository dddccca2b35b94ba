#include "deform/EdSolver.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <unordered_map>

#include "core/Error.h"
#include "core/ParallelFor.h"
#include "core/Progress.h"
#include "deform/BlockCholesky.h"

namespace splatwarp {

namespace {

using Mat9 = Eigen::Matrix<double, 9, 9>;
using Vec9 = Eigen::Matrix<double, 9, 1>;
using Mat93 = Eigen::Matrix<double, 9, 3>;
using M3 = Eigen::Matrix3d;
using V3 = Eigen::Vector3d;

// Levenberg damping on the diagonal: keeps the normal equations definite along the rigid-motion
// null space (e.g. a single handle node) without moving the fixed point (the gradient is zero there).
constexpr double kDamping = 1e-6;
// Backtracking halvings before the line search gives up.
constexpr int kMaxHalvings = 12;

V3 toEigen(const Vec3d& v) { return V3(v.x, v.y, v.z); }

/// The problem in normalised coordinates: x_n = (x - centre) / scale.
struct Problem {
    const DeformationGraph& graph;
    const EdOptions& options;
    V3 centre;
    double scale = 1.0;
    std::vector<V3> g;                 // [J] normalised rest positions
    std::vector<V3> target;            // [J] normalised targets
    std::vector<std::uint8_t> hasTarget;
    std::vector<int> freeIndex;        // [J] index among the unknowns, -1 when fixed
    std::vector<int> freeNodes;        // [F] node of each unknown

    Problem(const DeformationGraph& gr, const EdConstraints& c, const EdOptions& o) : graph(gr), options(o)
    {
        const std::size_t n = gr.nodeCount();
        if (c.fixed.size() != n || c.hasTarget.size() != n || c.target.size() != n)
            throw InputError(msg("ED constraints have ", c.fixed.size(), "/", c.hasTarget.size(), "/", c.target.size(),
                                 " entries for a graph of ", n, " nodes"));
        V3 lo = toEigen(gr.nodes()[0]), hi = lo;
        for (const Vec3d& p : gr.nodes()) {
            lo = lo.cwiseMin(toEigen(p));
            hi = hi.cwiseMax(toEigen(p));
        }
        centre = 0.5 * (lo + hi);
        scale = (hi - lo).maxCoeff();
        if (!(scale > 0.0)) scale = 1.0;
        g.resize(n);
        target.resize(n);
        hasTarget.resize(n);
        freeIndex.assign(n, -1);
        for (std::size_t j = 0; j < n; ++j) {
            g[j] = (toEigen(gr.nodes()[j]) - centre) / scale;
            target[j] = (toEigen(c.target[j]) - centre) / scale;
            hasTarget[j] = c.hasTarget[j] && !c.fixed[j];
            if (!c.fixed[j]) {
                freeIndex[j] = int(freeNodes.size());
                freeNodes.push_back(int(j));
            }
        }
    }
};

/// Unknowns of every node in normalised units (fixed nodes stay A = I, t = 0).
struct State {
    std::vector<M3> A;
    std::vector<V3> t;
};

void rotResiduals(const M3& a, double r[6])
{
    const V3 c0 = a.col(0), c1 = a.col(1), c2 = a.col(2);
    r[0] = c0.dot(c1); r[1] = c0.dot(c2); r[2] = c1.dot(c2);
    r[3] = c0.dot(c0) - 1.0; r[4] = c1.dot(c1) - 1.0; r[5] = c2.dot(c2) - 1.0;
}

V3 regResidual(const Problem& p, const State& s, std::size_t j, std::size_t k)
{
    return s.A[j] * (p.g[k] - p.g[j]) + p.g[j] + s.t[j] - p.g[k] - s.t[k];
}

EdEnergies energies(const Problem& p, const State& s)
{
    EdEnergies e;
    const std::size_t n = p.g.size();
    for (std::size_t j = 0; j < n; ++j) {
        if (p.freeIndex[j] >= 0) {
            double r[6];
            rotResiduals(s.A[j], r);
            for (double v : r) e.rot += v * v;
        }
        for (std::int32_t k : p.graph.neighbours(j)) e.reg += regResidual(p, s, j, std::size_t(k)).squaredNorm();
        if (p.hasTarget[j]) e.con += (p.g[j] + s.t[j] - p.target[j]).squaredNorm();
    }
    e.rot *= p.options.rotWeight;
    e.reg *= p.options.regWeight;
    e.con *= p.options.conWeight;
    return e;
}

/// Gauss-Newton normal equations with the per-node A blocks eliminated (Schur complement): no
/// residual couples two nodes' A, so H_AA is block diagonal (9x9 per node) and the reduced system
/// has 3 unknowns per free node. Its pattern is fixed, analysed once, factorised once per iteration
/// by a 3x3-block Cholesky (several times faster than Eigen's scalar SimplicialLDLT here).
class ReducedSystem {
public:
    explicit ReducedSystem(const Problem& p) : mP(p)
    {
        const std::size_t f = p.freeNodes.size();
        mSet.resize(f);
        mPairBlocks.resize(f);
        std::unordered_map<std::int64_t, int> blockOf;
        std::vector<std::pair<int, int>> blocks;
        auto blockId = [&](int a, int b) {
            const std::int64_t key = std::int64_t(a) * std::int64_t(f) + b;
            auto it = blockOf.find(key);
            if (it != blockOf.end()) return it->second;
            const int id = int(blocks.size());
            blockOf.emplace(key, id);
            blocks.emplace_back(a, b);
            return id;
        };
        for (std::size_t fi = 0; fi < f; ++fi) {
            const std::size_t j = std::size_t(p.freeNodes[fi]);
            mSet[fi].push_back(int(fi));
            for (std::int32_t k : p.graph.neighbours(j))
                if (p.freeIndex[std::size_t(k)] >= 0) mSet[fi].push_back(p.freeIndex[std::size_t(k)]);
            for (int a : mSet[fi])
                for (int b : mSet[fi]) mPairBlocks[fi].push_back(blockId(a, b));
        }
        mDiag.resize(f);
        for (std::size_t fi = 0; fi < f; ++fi) mDiag[fi] = blockId(int(fi), int(fi));
        mBlocks.resize(blocks.size());

        if (f > 0) mChol.analyze(int(f), blocks);
        mHaa.resize(f);
        mGa.resize(f);
        mHat.resize(f);
        mW.resize(f);
        mY.resize(f);
        mEdgePos.resize(f);
        mProd.resize(f);
        mRhsPart.resize(f);
        for (std::size_t fi = 0; fi < f; ++fi) {
            const std::size_t m = mSet[fi].size();
            mHat[fi].resize(m);
            mW[fi].resize(m);
            mProd[fi].resize(m * m);
            mRhsPart[fi].resize(m);
            for (std::int32_t k : p.graph.neighbours(std::size_t(p.freeNodes[fi]))) {
                const int fk = p.freeIndex[std::size_t(k)];
                mEdgePos[fi].push_back(fk < 0 ? 0 : std::size_t(std::find(mSet[fi].begin(), mSet[fi].end(), fk) - mSet[fi].begin()));
            }
        }
    }

    /// One Gauss-Newton step of every node (zero for fixed nodes). Returns false if singular.
    bool step(const State& s, State& delta)
    {
        const std::size_t f = mP.freeNodes.size();
        // 1. Node-local blocks of each free node j (parallel): H_AA, g_A from E_rot and from its
        //    out-edges (j,k), and H_{A_j, t_m} for m in {j} + free neighbours.
        forEachFree([&](std::size_t fi) { assembleNode(s, fi); });
        // 2. The translation blocks and right-hand side -g_t (serial: scalar diagonal updates only).
        Eigen::VectorXd rhs = Eigen::VectorXd::Zero(Eigen::Index(3 * f));
        assembleTranslations(s, rhs);
        // 3. Eliminate A (parallel per node, then a serial scatter):
        //    S = H_tt - H_tA H_AA^-1 H_At, rhs = -g_t + H_tA H_AA^-1 g_A.
        std::vector<std::uint8_t> ok(f, 1);
        forEachFree([&](std::size_t fi) { ok[fi] = eliminateNode(fi) ? 1 : 0; });
        if (std::find(ok.begin(), ok.end(), std::uint8_t(0)) != ok.end()) return false;
        scatterSchur(rhs);
        // 4. Solve for the translations, then recover each A.
        if (!mChol.factorize(mBlocks)) return false;
        const Eigen::VectorXd dt = mChol.solve(rhs);
        if (!dt.allFinite()) return false;
        backSubstitute(dt, delta);
        return true;
    }

private:
    /// Zero the translation blocks, then add E_reg, E_con and damping to them and -g_t to rhs.
    void assembleTranslations(const State& s, Eigen::VectorXd& rhs)
    {
        const Problem& p = mP;
        const EdOptions& o = p.options;
        for (M3& b : mBlocks) b.setZero();
        auto addDiag = [&](std::size_t blockId, double w) { mBlocks[blockId].diagonal().array() += w; };
        for (std::size_t j = 0; j < p.g.size(); ++j) {
            const int fj = p.freeIndex[j];
            const auto& nb = p.graph.neighbours(j);
            for (std::size_t e = 0; e < nb.size(); ++e) {
                const std::size_t k = std::size_t(nb[e]);
                const int fk = p.freeIndex[k];
                if (fj < 0 && fk < 0) continue;
                const V3 wr = o.regWeight * regResidual(p, s, j, k); // d r / d t_j = I, d r / d t_k = -I
                if (fj >= 0) {
                    addDiag(std::size_t(mDiag[std::size_t(fj)]), o.regWeight);
                    rhs.segment<3>(3 * fj) -= wr;
                }
                if (fk >= 0) {
                    addDiag(std::size_t(mDiag[std::size_t(fk)]), o.regWeight);
                    rhs.segment<3>(3 * fk) += wr;
                }
                if (fj >= 0 && fk >= 0) {
                    const std::size_t m = mSet[std::size_t(fj)].size(), pos = mEdgePos[std::size_t(fj)][e];
                    addDiag(std::size_t(mPairBlocks[std::size_t(fj)][pos]), -o.regWeight);     // (j,k)
                    addDiag(std::size_t(mPairBlocks[std::size_t(fj)][pos * m]), -o.regWeight); // (k,j)
                }
            }
            if (fj >= 0 && p.hasTarget[j]) {
                addDiag(std::size_t(mDiag[std::size_t(fj)]), o.conWeight);
                rhs.segment<3>(3 * fj) -= o.conWeight * (p.g[j] + s.t[j] - p.target[j]);
            }
        }
        for (std::size_t fi = 0; fi < p.freeNodes.size(); ++fi) addDiag(std::size_t(mDiag[fi]), kDamping);
    }

    /// Subtract every node's Schur products from the blocks and add its rhs parts, in node order.
    void scatterSchur(Eigen::VectorXd& rhs)
    {
        for (std::size_t fi = 0; fi < mP.freeNodes.size(); ++fi) {
            const std::vector<int>& set = mSet[fi];
            const std::size_t m = set.size();
            for (std::size_t a = 0; a < m; ++a) {
                rhs.segment<3>(3 * set[a]) += mRhsPart[fi][a];
                for (std::size_t b = 0; b < m; ++b) mBlocks[std::size_t(mPairBlocks[fi][a * m + b])] -= mProd[fi][a * m + b];
            }
        }
    }

    /// delta.t from the solved translations, delta.A = -y - sum W dt per free node; zero elsewhere.
    void backSubstitute(const Eigen::VectorXd& dt, State& delta) const
    {
        const std::size_t n = mP.g.size();
        delta.A.assign(n, M3::Zero());
        delta.t.assign(n, V3::Zero());
        for (std::size_t fi = 0; fi < mP.freeNodes.size(); ++fi) {
            const std::size_t j = std::size_t(mP.freeNodes[fi]);
            delta.t[j] = dt.segment<3>(3 * Eigen::Index(fi));
            Vec9 da = -mY[fi];
            for (std::size_t a = 0; a < mSet[fi].size(); ++a) da.noalias() -= mW[fi][a] * dt.segment<3>(3 * mSet[fi][a]);
            for (int col = 0; col < 3; ++col) delta.A[j].col(col) = da.segment<3>(3 * col);
        }
    }

    template <typename F>
    void forEachFree(const F& fn) const
    {
        parallelFor(mP.freeNodes.size(), 16, mP.options.threaded, fn);
    }

    /// H_AA, g_A and H_At of free node fi from E_rot and its out-edges.
    void assembleNode(const State& s, std::size_t fi)
    {
        const Problem& p = mP;
        const EdOptions& o = p.options;
        const std::size_t j = std::size_t(p.freeNodes[fi]);
        Mat9& haa = mHaa[fi];
        Vec9& ga = mGa[fi];
        std::vector<Mat93>& hat = mHat[fi];
        for (Mat93& h : hat) h.setZero();
        // E_rot: columns c_i of A are variables 3i..3i+2.
        double r[6];
        rotResiduals(s.A[j], r);
        Eigen::Matrix<double, 6, 9> jr = Eigen::Matrix<double, 6, 9>::Zero();
        const V3 c[3] = {s.A[j].col(0), s.A[j].col(1), s.A[j].col(2)};
        const int pairs[3][2] = {{0, 1}, {0, 2}, {1, 2}};
        for (int q = 0; q < 3; ++q) {
            jr.block<1, 3>(q, 3 * pairs[q][0]) = c[pairs[q][1]].transpose();
            jr.block<1, 3>(q, 3 * pairs[q][1]) = c[pairs[q][0]].transpose();
            jr.block<1, 3>(3 + q, 3 * q) = 2.0 * c[q].transpose();
        }
        const Eigen::Map<const Eigen::Matrix<double, 6, 1>> rv(r);
        haa.noalias() = o.rotWeight * jr.transpose().lazyProduct(jr);
        ga.noalias() = o.rotWeight * jr.transpose() * rv;
        haa.diagonal().array() += kDamping;
        // E_reg over out-edges: r_a = sum_b A[a][b] d_b + ..., so d r_a / d A[a][b] (variable 3b+a) = d_b.
        const auto& nb = p.graph.neighbours(j);
        for (std::size_t e = 0; e < nb.size(); ++e) {
            const std::size_t k = std::size_t(nb[e]);
            const V3 d = p.g[k] - p.g[j];
            const V3 res = regResidual(p, s, j, k);
            const M3 ddT = o.regWeight * d * d.transpose();
            for (int b = 0; b < 3; ++b)
                for (int cc = 0; cc < 3; ++cc)
                    for (int a = 0; a < 3; ++a) haa(3 * b + a, 3 * cc + a) += ddT(b, cc);
            for (int b = 0; b < 3; ++b)
                for (int a = 0; a < 3; ++a) {
                    ga(3 * b + a) += o.regWeight * d(b) * res(a);
                    hat[0](3 * b + a, a) += o.regWeight * d(b); // t_j
                }
            if (p.freeIndex[k] >= 0) {
                Mat93& hk = hat[mEdgePos[fi][e]];
                for (int b = 0; b < 3; ++b)
                    for (int a = 0; a < 3; ++a) hk(3 * b + a, a) -= o.regWeight * d(b); // t_k
            }
        }
    }

    /// Per-node Schur terms: W = H_AA^-1 H_At, y = H_AA^-1 g_A, products H_tA W and H_tA y.
    bool eliminateNode(std::size_t fi)
    {
        const Eigen::LLT<Mat9> llt(mHaa[fi]);
        if (llt.info() != Eigen::Success) return false;
        // One explicit inverse, then unrolled fixed-size products (lazyProduct): Eigen sends 9x9
        // products and triangular solves to its generic GEMM kernels, slow at this size.
        const Mat9 inv = llt.solve(Mat9::Identity());
        const std::size_t m = mSet[fi].size();
        for (std::size_t a = 0; a < m; ++a) mW[fi][a].noalias() = inv.lazyProduct(mHat[fi][a]);
        mY[fi].noalias() = inv.lazyProduct(mGa[fi]);
        for (std::size_t a = 0; a < m; ++a) {
            mRhsPart[fi][a].noalias() = mHat[fi][a].transpose().lazyProduct(mY[fi]);
            for (std::size_t b = 0; b < m; ++b) mProd[fi][a * m + b].noalias() = mHat[fi][a].transpose().lazyProduct(mW[fi][b]);
        }
        return true;
    }

    const Problem& mP;
    std::vector<std::vector<int>> mSet;        // [F] free node, then its free neighbours (unknown indices)
    std::vector<std::vector<int>> mPairBlocks; // [F][|set|^2] block id of (set[a], set[b])
    std::vector<int> mDiag;                    // [F] block id of (f, f)
    std::vector<M3> mBlocks;                   // values of the reduced matrix per 3x3 block
    BlockCholesky3 mChol;                      // the reduced matrix's factorisation
    std::vector<Mat9> mHaa;
    std::vector<Vec9> mGa;
    std::vector<std::vector<Mat93>> mHat;      // [F][|set|] H_{A_f, t_set[a]}
    std::vector<std::vector<Mat93>> mW;        // H_AA^-1 H_At
    std::vector<Vec9> mY;                      // H_AA^-1 g_A
    std::vector<std::vector<std::size_t>> mEdgePos; // [F][k] position of out-edge e's node in mSet (0 if fixed)
    std::vector<std::vector<M3>> mProd;        // [F][|set|^2] H_tA W per pair
    std::vector<std::vector<V3>> mRhsPart;     // [F][|set|] H_tA y
};

State toState(const Problem& p, const NodeTransforms* warm)
{
    const std::size_t n = p.g.size();
    State s;
    s.A.assign(n, M3::Identity());
    s.t.assign(n, V3::Zero());
    if (!warm) return s;
    if (warm->A.size() != n || warm->t.size() != n)
        throw InputError(msg("warm start has ", warm->t.size(), " transforms for ", n, " nodes"));
    for (std::size_t j = 0; j < n; ++j) {
        if (p.freeIndex[j] < 0) continue;
        for (int a = 0; a < 3; ++a)
            for (int b = 0; b < 3; ++b) s.A[j](a, b) = warm->A[j][a][b];
        s.t[j] = toEigen(warm->t[j]) / p.scale;
    }
    return s;
}

NodeTransforms fromState(const Problem& p, const State& s)
{
    const std::size_t n = p.g.size();
    NodeTransforms x = NodeTransforms::identity(n);
    for (std::size_t j = 0; j < n; ++j) {
        if (p.freeIndex[j] < 0) continue; // exactly identity
        for (int a = 0; a < 3; ++a)
            for (int b = 0; b < 3; ++b) x.A[j][a][b] = s.A[j](a, b);
        const V3 t = s.t[j] * p.scale;
        x.t[j] = Vec3d(t.x(), t.y(), t.z());
    }
    return x;
}

double freeNorm2(const Problem& p, const State& s)
{
    double sum = 0.0;
    for (int j : p.freeNodes) sum += s.A[std::size_t(j)].squaredNorm() + s.t[std::size_t(j)].squaredNorm();
    return sum;
}

} // namespace

EdConstraints EdConstraints::none(std::size_t n)
{
    EdConstraints c;
    c.fixed.assign(n, 0);
    c.hasTarget.assign(n, 0);
    c.target.assign(n, Vec3d(0, 0, 0));
    return c;
}

NodeTransforms solveEd(const DeformationGraph& graph, const EdConstraints& constraints, const EdOptions& options,
                       EdReport* report, const NodeTransforms* warmStart)
{
    const Stopwatch clock;
    const Problem p(graph, constraints, options);
    State s = toState(p, warmStart);
    EdReport rep;
    rep.freeNodes = p.freeNodes.size();
    rep.initial = energies(p, s);
    EdEnergies current = rep.initial;
    if (!p.freeNodes.empty()) {
        ReducedSystem system(p);
        State delta, trial;
        for (int it = 0; it < options.maxIterations; ++it) {
            if (!system.step(s, delta)) break;
            rep.iterations = it + 1;
            double stepNorm2 = 0.0;
            for (int j : p.freeNodes)
                stepNorm2 += delta.A[std::size_t(j)].squaredNorm() + delta.t[std::size_t(j)].squaredNorm();
            const double xNorm = std::sqrt(freeNorm2(p, s));
            double alpha = 1.0;
            bool accepted = false;
            for (int h = 0; h <= kMaxHalvings; ++h, alpha *= 0.5) {
                trial = s;
                for (int j : p.freeNodes) {
                    trial.A[std::size_t(j)] += alpha * delta.A[std::size_t(j)];
                    trial.t[std::size_t(j)] += alpha * delta.t[std::size_t(j)];
                }
                const EdEnergies e = energies(p, trial);
                if (e.total() <= current.total()) {
                    s.A.swap(trial.A);
                    s.t.swap(trial.t);
                    current = e;
                    accepted = true;
                    break;
                }
            }
            const double step = alpha * std::sqrt(stepNorm2);
            if (step <= options.relativeStep * (xNorm + options.relativeStep)) {
                rep.converged = true;
                break;
            }
            if (!accepted) break; // no decrease along the Gauss-Newton direction: numerical floor
        }
    } else {
        rep.converged = true;
    }
    rep.final = current;
    rep.ms = clock.ms();
    if (report) *report = rep;
    return fromState(p, s);
}

} // namespace splatwarp
