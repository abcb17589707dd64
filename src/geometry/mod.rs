//! Shape geometry on point sets and meshes: rigid registration (CPD), nearest-neighbour
//! queries, PCA. Pure: no async, SQL or HTTP.
