#include "edit/DragSpec.h"

#include <nlohmann/json.hpp>

namespace splatwarp::edit {

std::string bendDragSpec(double degrees)
{
    return nlohmann::json{
        {"version", 1},
        {"units", "bbox"},
        {"handles",
         {{{"box", {{"min", {-0.01, -0.01, -0.01}}, {"max", {0.1, 1.01, 1.01}}}}, {"fixed", true}},
          {{"box", {{"min", {0.9, -0.01, -0.01}}, {"max", {1.01, 1.01, 1.01}}}},
           {"rotate", {{"axis", {0, 0, 1}}, {"degrees", degrees}}},
           {"pivot", {0.5, 1.05, 0.5}}}}}}
        .dump();
}

} // namespace splatwarp::edit
