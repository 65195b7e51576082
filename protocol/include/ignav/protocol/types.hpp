// A plain C++ value per topic (protocol/idl/ignav.idl says what each field means), and each
// value's one list of fields. The list gives the JSON view (json_view.hpp) and the conversion to
// and from the C sample (wire/messages.hpp): adding a field to a topic is the IDL, the member and
// its line in the list that follows the value (request_types.hpp: requests and replies;
// state_types.hpp: the state topics). Lengths in mm, angles in rad, matrices row-major 4x4.
//
// No DDS and no generated code: tools include this and link ignav::protocol_types alone.
#pragma once

#include "ignav/protocol/request_types.hpp"
#include "ignav/protocol/state_types.hpp"
#include "ignav/protocol/values.hpp"
