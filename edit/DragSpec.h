#pragma once
/// @file DragSpec.h
/// @brief The pose `bench edit` drags through (and the tests pose): samples/specs/bend.json's
///        handles with the +x end turned by a given angle, as a spec JSON text.
#include <string>

namespace splatwarp::edit {

/// @brief The -x end (10% of the box) fixed, the +x end turned about z by `degrees` about the
///        pivot (0.5, 1.05, 0.5), in bbox units; the graph block left to the session.
std::string bendDragSpec(double degrees);

} // namespace splatwarp::edit
