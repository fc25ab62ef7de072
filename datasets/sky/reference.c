/* Reference values of the Hosek-Wilkie sky and solar disk, printed by the authors' own code.
 *
 * Built and run by datasets/sky/reference.sh against the reference implementation v1.4a
 * (ArHosekSkyModel.c and its data headers, BSD 3-clause, Lukas Hosek and Alexander Wilkie),
 * which it links unchanged. igi's Rust port (crates/sky) is tested against what this prints;
 * nothing here comes from that port.
 *
 * sky.csv: arhosek_rgb_skymodelstate_alloc_init + arhosek_tristim_skymodel_radiance.
 * sun.csv: arhosekskymodel_solar_radiance_internal2 (spectral state of
 *   arhosekskymodelstate_alloc_init, the model's disk of radius 0.255 degrees) turned into
 *   linear Rec. 709 RGB: XYZ = trapezoid rule on 1 nm steps over 360..720 nm of
 *   L(lambda) * {x,y,z}-bar(lambda) (CIE 1931 2 degree, cie.h), then the sRGB matrix below.
 *   Rows with gamma_deg >= 0 are the radiance at that angle from the disk's centre; the row
 *   with gamma_deg = -1 is the disk's irradiance at normal incidence, integral of L dOmega,
 *   by a midpoint rule over 4000 rings of the disk.
 * consistency (stdout): the RGB sky against the CIE XYZ sky put through the same matrix
 *   (with SKY_RATIOS set, each ratio too: turbidity, elevation, theta, gamma, channel, ratio).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include "ArHosekSkyModel.h"
#include "cie.h" /* CIE_X, CIE_Y, CIE_Z: 471 values, 360..830 nm */

/* defined in ArHosekSkyModel.c, not declared in its header */
double arhosekskymodel_solar_radiance_internal2(ArHosekSkyModelState *state, double wavelength,
                                                double elevation, double gamma);

static const double PI = 3.141592653589793;
/* linear sRGB (Rec. 709 primaries, D65) from XYZ (Lindbloom's matrix) */
static const double M[3][3] = {{3.2404542, -1.5371385, -0.4985314},
                               {-0.9692660, 1.8760108, 0.0415560},
                               {0.0556434, -0.2040259, 1.0572252}};

static void to_rgb(const double xyz[3], double rgb[3]) {
    for (int i = 0; i < 3; i++)
        rgb[i] = M[i][0] * xyz[0] + M[i][1] * xyz[1] + M[i][2] * xyz[2];
}

static void solar_rgb(ArHosekSkyModelState *s, double elev, double gamma, double rgb[3]) {
    double xyz[3] = {0, 0, 0};
    for (int nm = 360; nm <= 720; nm++) {
        double w = (nm == 360 || nm == 720) ? 0.5 : 1.0;
        double l = arhosekskymodel_solar_radiance_internal2(s, (double)nm, elev, gamma);
        xyz[0] += w * l * CIE_X[nm - 360];
        xyz[1] += w * l * CIE_Y[nm - 360];
        xyz[2] += w * l * CIE_Z[nm - 360];
    }
    to_rgb(xyz, rgb);
}

int main(void) {
    FILE *f = fopen("sky.csv", "w");
    fprintf(f, "# Hosek-Wilkie RGB sky radiance, printed by the reference code v1.4a (datasets/sky/reference.c)\n");
    fprintf(f, "turbidity,albedo,elevation_deg,theta_deg,gamma_deg,r,g,b\n");
    const double turb[] = {1, 3.3, 6.5, 10};
    const double alb[] = {0, 0.5, 1};
    const double elev[] = {0, 5, 20, 45, 70, 90};
    const double theta[] = {0, 45, 80, 90};
    const double gamma[] = {0, 5, 30, 90, 170};
    for (int a = 0; a < 4; a++)
        for (int b = 0; b < 3; b++)
            for (int c = 0; c < 6; c++) {
                ArHosekSkyModelState *s =
                    arhosek_rgb_skymodelstate_alloc_init(turb[a], alb[b], elev[c] * PI / 180);
                for (int d = 0; d < 4; d++)
                    for (int e = 0; e < 5; e++) {
                        double v[3];
                        for (int ch = 0; ch < 3; ch++)
                            v[ch] = arhosek_tristim_skymodel_radiance(s, theta[d] * PI / 180,
                                                                      gamma[e] * PI / 180, ch);
                        fprintf(f, "%g,%g,%g,%g,%g,%.17g,%.17g,%.17g\n", turb[a], alb[b], elev[c],
                                theta[d], gamma[e], v[0], v[1], v[2]);
                    }
                arhosekskymodelstate_free(s);
            }
    fclose(f);

    f = fopen("sun.csv", "w");
    fprintf(f, "# Hosek-Wilkie solar disk, linear Rec. 709 RGB of the reference code's spectral solar radiance v1.4a (datasets/sky/reference.c); gamma_deg -1: the disk's irradiance\n");
    fprintf(f, "turbidity,elevation_deg,gamma_deg,r,g,b\n");
    const double sturb[] = {1, 2, 3.3, 6.5, 10};
    const double selev[] = {0, 2, 10, 30, 60, 90};
    const double sgam[] = {0, 0.1, 0.2, 0.25};
    for (int a = 0; a < 5; a++)
        for (int c = 0; c < 6; c++) {
            double el = selev[c] * PI / 180;
            ArHosekSkyModelState *s = arhosekskymodelstate_alloc_init(el, sturb[a], 0.0);
            for (int e = 0; e < 4; e++) {
                double v[3];
                solar_rgb(s, el, sgam[e] * PI / 180, v);
                fprintf(f, "%g,%g,%g,%.17g,%.17g,%.17g\n", sturb[a], selev[c], sgam[e], v[0], v[1],
                        v[2]);
            }
            const int rings = 4000;
            double r = s->solar_radius, dg = r / rings, e3[3] = {0, 0, 0};
            for (int i = 0; i < rings; i++) {
                double g = (i + 0.5) * dg, v[3];
                solar_rgb(s, el, g, v);
                for (int ch = 0; ch < 3; ch++) e3[ch] += v[ch] * 2 * PI * sin(g) * dg;
            }
            fprintf(f, "%g,%g,-1,%.17g,%.17g,%.17g\n", sturb[a], selev[c], e3[0], e3[1], e3[2]);
            arhosekskymodelstate_free(s);
        }
    fclose(f);

    /* how the RGB data relate to the XYZ data: the largest relative difference per channel */
    double worst[3] = {0, 0, 0}, sum[3] = {0, 0, 0};
    int n = 0;
    for (int a = 0; a < 4; a++)
        for (int c = 0; c < 6; c++) {
            ArHosekSkyModelState *s = arhosek_rgb_skymodelstate_alloc_init(turb[a], 0.3, elev[c] * PI / 180);
            ArHosekSkyModelState *x = arhosek_xyz_skymodelstate_alloc_init(turb[a], 0.3, elev[c] * PI / 180);
            for (int d = 0; d < 3; d++)
                for (int e = 0; e < 5; e++) {
                    double xyz[3], rgb[3];
                    for (int ch = 0; ch < 3; ch++)
                        xyz[ch] = arhosek_tristim_skymodel_radiance(x, theta[d] * PI / 180, gamma[e] * PI / 180, ch);
                    to_rgb(xyz, rgb);
                    for (int ch = 0; ch < 3; ch++) {
                        double m = arhosek_tristim_skymodel_radiance(s, theta[d] * PI / 180, gamma[e] * PI / 180, ch);
                        double rel = fabs(rgb[ch] / m - 1);
                        if (getenv("SKY_RATIOS")) printf("%g %g %g %g %d %g\n", turb[a], elev[c], theta[d], gamma[e], ch, rgb[ch] / m);
                        if (rel > worst[ch]) worst[ch] = rel;
                        sum[ch] += rel;
                    }
                    n++;
                }
            arhosekskymodelstate_free(s);
            arhosekskymodelstate_free(x);
        }
    printf("RGB sky vs sRGB matrix x XYZ sky, albedo 0.3, %d directions: mean |rel| %.4f %.4f %.4f, max %.4f %.4f %.4f\n",
           n, sum[0] / n, sum[1] / n, sum[2] / n, worst[0], worst[1], worst[2]);
    return 0;
}
