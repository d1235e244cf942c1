#pragma once
// The row of a rolling-shutter image that its time stamp refers to (docs/sim.md, `stamp_row`):
// one meaning for the simulator, the survey, the database and the localiser.

#include "lookup/common/options_table.h"

namespace lookup::common {

enum class StampRow {
    First,  ///< the start of the frame (V4L2 / UVC drivers)
    Middle  ///< the central row (an offset set to the central row's time)
};

/// As the .ini files spell them: "first", "middle".
inline const EnumNames<StampRow>& stampRowNames() {
    static const EnumNames<StampRow> names = {{"first", StampRow::First},
                                              {"middle", StampRow::Middle}};
    return names;
}

}  // namespace lookup::common
