//! Evaluation of shape models: surface distances, biomarkers, clinical acceptance.
//! Pure: no async, SQL or HTTP.
