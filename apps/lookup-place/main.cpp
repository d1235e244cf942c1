// lookup-place: builds or evaluates a database's ceiling place index (lookup/place/place_app.h).
#include "lookup/common/app.h"
#include "lookup/place/place_app.h"

int main(int argc, char** argv) {
    lookup::place::PlaceApp app;
    return lookup::common::runApp("lookup-place", app, argc, argv);
}
