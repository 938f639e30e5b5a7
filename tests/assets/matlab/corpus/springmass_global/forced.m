close all;
clear all;

global mass kstiff cdamp zeta famp fomega;

kstiff = 3;
mass = 0.8;
zeta = 0.1;
cdamp = zeta * 2 * sqrt(kstiff*mass);
famp = 2;
wn = sqrt(kstiff/mass);
fomega = 0.9 * wn;

opt = odeset('maxStep', 1e-2);
[t,z] = ode45(@springmass, [0 30], [0 0], opt);
plot(t,z(:,1)*kstiff/famp);
