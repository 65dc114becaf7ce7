"""Citations of the papers cwproc implements, one home for each.

Every module that cites a paper in a product attribute or a docstring table takes
the text from here, so that a citation is written once.
"""

SMALIKHO_2020 = (
    "Smalikho I.N. (2020), Wind transfer of turbulent inhomogeneities when estimating the "
    "dissipation rate from a conically scanning coherent Doppler lidar. Part I. Theory, "
    "Atmos. Oceanic Opt."
)
BANAKH_1999 = (
    "Banakh V.A., Werner Ch., Krivolutskii N.P., Smalikho I.N. (1999), Computer simulation "
    "of cw Doppler wind lidar operation in a turbulent atmosphere, Atmos. Oceanic Opt."
)
GLADKIKH_2014 = (
    "Gladkikh V.A., Nevzorova I.V., Odintsov S.L., Fedorov V.A. (2014), Structure functions "
    "of wind velocity components over an inhomogeneous underlying surface, Atmos. Oceanic Opt."
)
WAGNER_DTU = (
    "Wagner R., Mikkelsen T., Courtney M. (DTU), Investigation of turbulence measurements "
    "with a continuous wave, conically scanning lidar, Risoe-R report."
)

SATHE_2011 = (
    "Sathe A., Mann J., Gottschall J., Courtney M.S. (2011), Can wind lidars measure "
    "turbulence?, J. Atmos. Oceanic Technol. 28, 853-868"
)
SATHE_MANN_2013 = (
    "Sathe A., Mann J. (2013), A review of turbulence measurements using ground-based "
    "wind lidars, Atmos. Meas. Tech. 6, 3147-3167"
)

OCONNOR_2010 = (
    "O'Connor E.J., Illingworth A.J., Brooks I.M., Westbrook C.D., Hogan R.J., Davies F., "
    "Brooks B.J. (2010), A method for estimating the turbulent kinetic energy dissipation "
    "rate from a vertically pointing Doppler lidar, and independent evaluation from "
    "balloon-borne in situ measurements, J. Atmos. Oceanic Technol. 27, 1652-1664"
)

PEARSON_2009 = (
    "Pearson, G., Davies, F. and Collier, C. (2009), An analysis of the performance of the "
    "UFAM pulsed Doppler lidar for observing the boundary layer, J. Atmos. Oceanic "
    "Technol. 26, 240-250"
)
RYE_HARDESTY_1993 = (
    "Rye, B. J. and Hardesty, R. M. (1993), Discrete spectral peak estimation in "
    "incoherent backscatter heterodyne lidar. I, IEEE Trans. Geosci. Remote Sens. 31, 16-27"
)

#: the VAD error theory; the available text gives neither the authors nor the year
VAD_ACCURACY = (
    "Theoretical accuracy of wind-vector reconstruction from lidar VAD scanning "
    "(in Russian; authors and year not given in the available text)"
)

#: the papers of the VAD wind fit (the wind product's ``vad_references`` attribute and
#: the references of its wind variables)
VAD_WIND = (
    f"{SMALIKHO_2020}, eqs. 1 and 8; {BANAKH_1999}, after eq. 23; {VAD_ACCURACY}, sections 2-4"
)

EFRON_STEIN_1981 = (
    "Efron, B. and Stein, C. (1981), The jackknife estimate of variance, Ann. Statist. 9, 586-596"
)

PENTIKAINEN_2020 = (
    "Pentikäinen, P., O'Connor, E. J., Manninen, A. J. and Ortiz-Amezcua, P. (2020), "
    "Methodology for deriving the telescope focus function and its uncertainty for a "
    "heterodyne pulsed Doppler lidar, Atmos. Meas. Tech. 13, 2849-2863, "
    "doi:10.5194/amt-13-2849-2020"
)
VAKKARI_2021 = (
    "Vakkari, V., Baars, H., Bohlmann, S., Bühl, J., Komppula, M., Mamouri, R.-E. and "
    "O'Connor, E. J. (2021), Aerosol particle depolarization ratio at 1565 nm measured "
    "with a Halo Doppler lidar, Atmos. Chem. Phys. 21, 5807-5820, doi:10.5194/acp-21-5807-2021"
)
MANNINEN_2016 = (
    "Manninen, A. J., O'Connor, E. J., Vakkari, V. and Petäjä, T. (2016), A generalised "
    "background correction algorithm for a Halo Doppler lidar and its application to data "
    "from Finland, Atmos. Meas. Tech. 9, 817-827, doi:10.5194/amt-9-817-2016"
)
#: the ACTRIS Cloudnet Doppler lidar processing (its noise mask on intensity and velocity)
DOPPY = (
    "doppy, the ACTRIS Cloudnet Doppler lidar processing, version 0.5 "
    "(https://github.com/actris-cloudnet/doppy), product/stare.py noise mask"
)
BAYLEY_HAMMERSLEY_1946 = (
    'Bayley, G. V. and Hammersley, J. M. (1946), The "effective" number of independent '
    "observations in an autocorrelated time series, J. R. Stat. Soc. Suppl. 8, 185-197"
)
