/// Formats implemented above src/io, registered before main() runs (every tools/ object is linked
/// into the CLI, so this initialiser always runs): OpenVDB point grids for every model reader.
#include "vdb/VdbPoints.h"

namespace splatwarp::cli {
namespace {

const bool kVdbPointsRegistered = (registerVdbPointFormat(), true);

} // namespace
} // namespace splatwarp::cli
