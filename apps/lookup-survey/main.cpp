// lookup-survey: reference database from survey rawlogs (see lookup/survey/survey_app.h).
#include "lookup/common/app.h"
#include "lookup/survey/survey_app.h"

int main(int argc, char** argv) {
    lookup::survey::SurveyApp app;
    return lookup::common::runApp("lookup-survey", app, argc, argv);
}
