// lookup-survey: reference database from survey rawlogs (see lookup/survey/survey_app.h).
#include "lookup/common/errors.h"
#include "lookup/survey/survey_app.h"

int main(int argc, char** argv) {
    return lookup::common::guardedMain("lookup-survey", argc, argv, [&] {
        lookup::survey::SurveyApp app;
        if (!app.initialize(argc, argv)) return app.exitCode();
        return app.run();
    });
}
